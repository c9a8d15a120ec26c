"""Two systems' authorities, and so the issuers of their hosts' certificates, read differently in
`iotad certs show`: each authority is named after its system, and each certificate's line shows
the fingerprint of the key that signed it (SHA-256 of its SubjectPublicKeyInfo, computed here with
the cryptography library from the authority's own file)."""
import re
import subprocess
import sys

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization


def certs(cwd, *args):
    return subprocess.run([sys.executable, "-m", "iotad", "certs", *args], capture_output=True, text=True,
                          timeout=60, cwd=cwd)


def key_fingerprint(pem_path) -> str:
    public = x509.load_pem_x509_certificate(pem_path.read_bytes()).public_key()
    digest = hashes.Hash(hashes.SHA256())
    digest.update(public.public_bytes(serialization.Encoding.DER, serialization.PublicFormat.SubjectPublicKeyInfo))
    return digest.finalize().hex(":").upper()


def test_two_systems_arm_certificates_show_different_issuers(tmp_path):
    (tmp_path / "split.toml").write_text('[system]\nname = "split"\n')
    made = certs(tmp_path, "init", "one", "--system", "split.toml")
    assert made.returncode == 0 and "'split certificate authority'" in made.stdout, made.stderr
    assert certs(tmp_path, "init", "two", "--name", "conveyor").returncode == 0
    (tmp_path / "robot").mkdir()
    assert certs(tmp_path / "robot", "init", "certs").returncode == 0  # named after the folder it is in
    lines = {}
    for folder in ("one", "two", "robot/certs"):
        assert certs(tmp_path, "host", "arm", "--dir", folder).returncode == 0
        shown = certs(tmp_path, "show", f"{folder}/arm.pem", f"{folder}/ca.pem")
        assert shown.returncode == 0, shown.stderr
        lines[folder] = shown.stdout.splitlines()
    issuers = {}
    for folder, system in (("one", "split"), ("two", "conveyor"), ("robot/certs", "robot")):
        arm, authority = lines[folder]
        assert f"issued by CN={system} certificate authority" in arm, arm
        fingerprint = key_fingerprint(tmp_path / folder / "ca.pem")
        # the host's line names its issuer's key, and so does the authority's own (self-signed) line
        assert f"issuer fingerprint sha256 {fingerprint})" in arm and f"issuer fingerprint sha256 {fingerprint})" in authority
        issuers[folder] = re.search(r"issued by (.*?); valid", arm).group(1)
    assert len(set(issuers.values())) == 3


def test_without_its_authority_beside_a_certificate_shows_the_key_id_it_carries(tmp_path):
    assert certs(tmp_path, "init", "ca", "--name", "split").returncode == 0
    assert certs(tmp_path, "host", "arm", "--dir", "ca").returncode == 0
    alone = tmp_path / "arm.pem"
    alone.write_bytes((tmp_path / "ca" / "arm.pem").read_bytes())
    shown = certs(tmp_path, "show", "arm.pem")
    identifier = x509.load_pem_x509_certificate(alone.read_bytes()).extensions.get_extension_for_class(
        x509.AuthorityKeyIdentifier).value.key_identifier
    assert f"issuer fingerprint sha1 key id {identifier.hex(':').upper()})" in shown.stdout, shown.stdout


def test_a_system_file_without_a_name_is_refused_in_one_line(tmp_path):
    (tmp_path / "nameless.toml").write_text("[system]\n")
    refused = certs(tmp_path, "init", "ca", "--system", "nameless.toml")
    assert refused.returncode == 2 and refused.stderr.strip() == "iotad: error: certs init: nameless.toml has no [system] name"
    assert not (tmp_path / "ca").exists()
