"""Links between hosts are TLS with mutual authentication: a session that shows a certificate of
the system's own authority is admitted and its messages arrive; one without a certificate, or
with a certificate of another authority, cannot open a session at all. Loopback only."""
import stat
import time

import pytest
import zenoh

from iotad.machine import certificates



from iotad.node_host import transport


@pytest.fixture
def authority(tmp_path):
    certificates.init_authority(tmp_path / "ca", name="robot")
    return tmp_path / "ca"


def test_authority_and_host_files_are_private_and_name_the_host(authority):
    files = certificates.issue_host(authority, "arm", ["127.0.0.1", "arm.local"])
    assert stat.S_IMODE(files.key.stat().st_mode) == 0o600
    assert stat.S_IMODE((authority / "ca.key").stat().st_mode) == 0o600
    line = certificates.describe(files.certificate)
    assert "CN=arm" in line and "127.0.0.1" in line and "arm.local" in line and "CN=robot certificate authority" in line
    assert certificates.host_files(authority, "arm") == files


def test_refuses_to_replace_an_authority_or_a_host_and_bad_names(authority, tmp_path):
    with pytest.raises(certificates.CertificateError, match="invalidate every host certificate"):
        certificates.init_authority(authority)
    certificates.issue_host(authority, "arm")
    with pytest.raises(certificates.CertificateError, match="exists"):
        certificates.issue_host(authority, "arm")
    with pytest.raises(certificates.CertificateError, match="host name"):
        certificates.issue_host(authority, "../etc")
    with pytest.raises(certificates.CertificateError, match="neither an IP address nor a DNS name"):
        certificates.issue_host(authority, "base", ["not an address!"])
    with pytest.raises(certificates.CertificateError, match="no certificate authority"):
        certificates.issue_host(tmp_path / "nowhere", "arm")
    with pytest.raises(certificates.CertificateError, match="iotad certs host brain"):
        certificates.host_files(authority, "brain")


def test_only_a_certificate_of_the_authority_opens_a_session(authority, tmp_path):
    hub = certificates.issue_host(authority, "brain", ["127.0.0.1"])
    arm = certificates.issue_host(authority, "arm", ["127.0.0.1"])
    certificates.init_authority(tmp_path / "other")
    stranger = certificates.issue_host(tmp_path / "other", "arm")
    endpoint = f"tls/127.0.0.1:{transport.free_port()}"
    received = []
    with transport.open_session([endpoint], [], credentials=False, tls=hub) as session:
        session.declare_subscriber("robot/**", lambda sample: received.append(bytes(sample.payload)))
        with transport.open_session([], [endpoint], mode="client", connect_timeout=5, credentials=False,
                                    tls=arm) as client:
            publisher = client.declare_publisher("robot/joint")
            deadline = time.monotonic() + 10
            while not received and time.monotonic() < deadline:  # until the subscription is known
                publisher.put(b"0.5")
                time.sleep(0.05)
        assert received and set(received) == {b"0.5"}
        for files in (None, stranger):
            with pytest.raises(zenoh.ZError, match="Unable to connect"):
                transport.open_session([], [endpoint], mode="client", connect_timeout=1.5, credentials=False,
                                       tls=files)


def test_the_certs_command_makes_shows_and_refuses_in_one_line(tmp_path):
    import subprocess
    import sys

    def certs(*args):
        return subprocess.run([sys.executable, "-m", "iotad", "certs", *args], capture_output=True, text=True,
                              timeout=60, cwd=tmp_path)

    assert certs("init", "ca").returncode == 0
    made = certs("host", "arm", "--dir", "ca", "--address", "10.0.0.2")
    assert made.returncode == 0 and "signed ca/arm.pem" in made.stdout
    shown = certs("show", "ca/arm.pem")
    assert "CN=arm" in shown.stdout and "10.0.0.2" in shown.stdout
    again = certs("init", "ca")
    assert again.returncode == 2 and again.stderr.startswith("iotad: error: ") and "Traceback" not in again.stderr
    assert len(again.stderr.strip().splitlines()) == 1
