"""A host's router as a process of its own, for tests that stop it (SIGSTOP) to make it a link
that takes nothing more, as a cut host's is: it links to the hub as the host's launcher user,
subscribes to KEY, prints its zenoh id and `heard` once a sample arrived, and closes when its
stdin does.

    python tests/router_child.py SYSTEM_FILE HOST CREDENTIALS_FILE CERTS HUB_ENDPOINT KEY [PATH=JSON ...]

PATH=JSON: zenoh config settings added to the router's own."""
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from iotad.machine import certificates  # noqa: E402
from iotad.node_host.transport import open_session  # noqa: E402
from iotad.launcher.access.access_control import AccessControl  # noqa: E402
from iotad.launcher.system.system_file import load_system  # noqa: E402


def main() -> None:
    system_file, host, given, certs, hub, key, *settings = sys.argv[1:]
    access = AccessControl(load_system(Path(system_file)), given=given)
    endpoint = access.route(host)
    options = access.hub_options()
    options["extra"].update({path: json.loads(value) for path, value in (s.split("=", 1) for s in settings)})
    session = open_session([endpoint], [hub], tls=certificates.host_files(certs, host), **options)
    heard = []

    def on_sample(sample) -> None:
        if not heard:
            heard.append(True)
            print("heard", flush=True)

    try:
        subscriber = session.declare_subscriber(key, on_sample)
        print(f"zid {session.info.zid()}", flush=True)
        sys.stdin.read()  # until the test closes it
        subscriber.undeclare()
    finally:
        session.close()
        access.close()


if __name__ == "__main__":
    main()
