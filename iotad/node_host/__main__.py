"""`python -m iotad.node_host CONFIG.json`: run one IOTA as one process on zenoh until SIGINT/SIGTERM.

Prints nothing on stdout. A bad config, a spec that fails to load or a port that cannot open (a
CAN bus, a zenoh endpoint) is reported on stderr and exits with CONFIGURATION_ERROR (2), which
its launcher does not restart; a clean stop exits 0; an engine that dies or halts exits 1.
"""
from __future__ import annotations

import argparse
import gc
import signal
import sys

from iotad.node_host.node_config import CONFIGURATION_ERROR, ConfigError, load, parse
from iotad.node_host.stop_signals import StopSignals


def _fail(message: str, code: int = CONFIGURATION_ERROR) -> int:
    print(f"iotad.node_host: error: {message}", file=sys.stderr, flush=True)
    return code


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m iotad.node_host", description=__doc__)
    parser.add_argument("config", nargs="?", help="the node's JSON config file (docs/internals.md)")
    parser.add_argument("--config-json", help="the same JSON, inline")
    args = parser.parse_args(argv)
    if (args.config is None) == (args.config_json is None):
        return _fail("give a CONFIG.json file or --config-json, not both and not neither")

    # Signals first: a launcher may stop us while we are still importing zenoh or the spec.
    # SIGINT is how a launcher stops its nodes (and Ctrl-C): a clean stop, exit 0. SIGTERM from
    # anyone else (kill, a service manager) ends the node as a kill does, 128 + 15 as a shell
    # reports it: under restart = "on-failure" its launcher starts it again.
    # (No threading.Event set in the handler: it deadlocks when the signal lands while this
    # thread waits on that Event; iotad.node_host.stop_signals.)
    stop = StopSignals((signal.SIGTERM, signal.SIGINT))
    received = stop.received

    try:
        config = load(args.config) if args.config else parse(args.config_json, "--config-json")
    except ConfigError as exc:
        return _fail(str(exc))

    from iotad.node_host.node_host import NodeHost, SpecLoadError, load_root

    try:
        root, text = load_root(config)
    except SpecLoadError as exc:
        return _fail(f"{config.path}: cannot load its IOTA:\n{exc}")
    try:
        host = NodeHost(config, root, text)
    except ConfigError as exc:
        return _fail(str(exc))
    except Exception as exc:  # noqa: BLE001 - e.g. a composite whose bindings do not fit
        return _fail(f"{config.path}: {type(exc).__name__}: {exc}")
    if stop.is_set():
        return _signalled(received)
    try:
        from iotad.node_host.can_port import CanPortError

        try:
            host.start(settle=_freeze_heap)
        except CanPortError as exc:
            return _fail(f"{config.path}: {exc}")
        except Exception as exc:  # noqa: BLE001 - zenoh rejects an endpoint, a port is taken...
            return _fail(f"{config.path}: cannot start on zenoh: {_refused(config, exc)}".splitlines()[0])
        while not stop.wait(0.25):
            if not host.alive():
                break
    finally:
        host.close()
    if host.error is not None:
        return _fail(f"{config.path}: engine failed: {type(host.error).__name__}: {host.error}", 1)
    if host.engine.halted:
        return _fail(f"{config.path}: engine halted (see the zeno violation on @trace)", 1)
    return _signalled(received)


def _refused(config, exc: Exception) -> str:
    """zenoh's reason, or for a node given credentials (under access control) why the hub did not
    admit it: its certificate or its credentials, said in one line (iotad/node_host/admission.py)."""
    from iotad.node_host.credentials import CredentialsError, from_env

    try:
        own = from_env()
    except CredentialsError as refused:
        return str(refused)
    if own is None or not config.connect:
        return str(exc)
    from iotad.node_host.admission import diagnose
    from iotad.machine.certificates import CertificateError, from_env as tls_from_env

    try:
        tls = tls_from_env()
    except CertificateError as refused:
        return str(refused)
    return f"not admitted: {diagnose(config.connect[0], tls, own.user).reason}"


def _freeze_heap() -> None:
    """Everything made so far (modules, the spec, zenoh objects) lives as long as the node: keep it
    out of the collector's full passes, which would otherwise stall the engine thread. Run on the
    engine thread before the engine starts: collected in the main thread while the engine ran,
    it held the interpreter for milliseconds as the first windows closed (deadline misses)."""
    gc.collect()
    gc.freeze()


def _signalled(received: list[int]) -> int:
    """The exit status of a node stopped by `received` signals (none: it ended by itself)."""
    if received and received[0] == signal.SIGTERM:
        return 128 + signal.SIGTERM
    return 0


if __name__ == "__main__":
    sys.exit(main())
