"""Certificates for links between hosts: a system's own certificate authority, and one certificate
per host signed by it, for zenoh's TLS transport with mutual authentication (both ends show a
certificate of the same authority; a process without one cannot open a session).

Why our own authority and not a public one: the hosts of a robot are named by the people who
build it (`arm`, `brain`, 10.0.0.7), not by DNS, and nothing outside the robot should be
trusted to vouch for them. Keys are EC P-256 in PKCS#8 PEM, which zenoh's rustls reads; every
certificate is good for server and client use, since a host both listens and connects."""
from __future__ import annotations

import datetime
import ipaddress
import os
import re
from dataclasses import dataclass
from pathlib import Path

# A process of a system that links its hosts by TLS finds its certificates here: the folder and
# the name of the host it runs on (the launcher, an agent, or the user of a tool sets them).
ENV_DIR = "IOTAD_CERTS"
ENV_HOST = "IOTAD_CERTS_HOST"
AUTHORITY_CERTIFICATE = "ca.pem"
AUTHORITY_KEY = "ca.key"
_HOST_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,62}$")


class CertificateError(Exception):
    """A certificate directory, host name or address that cannot give a working certificate."""


@dataclass(frozen=True)
class TlsFiles:
    """What one zenoh session needs for mutual TLS: the authority that vouches for every host, and
    this host's certificate and key."""
    authority: Path
    certificate: Path
    key: Path

    def zenoh_tls(self) -> dict:
        """The `transport/link/tls` section of a zenoh configuration (zenoh 1.x names): the same
        certificate serves when listening and when connecting, and the peer must show one too."""
        return {
            "root_ca_certificate": str(self.authority),
            "listen_private_key": str(self.key),
            "listen_certificate": str(self.certificate),
            "connect_private_key": str(self.key),
            "connect_certificate": str(self.certificate),
            "enable_mtls": True,
            # hosts are reached by address and named by their people: the authority, not the
            # name in the URL, is what proves who is at the other end
            "verify_name_on_connect": False,
        }


def host_files(directory: str | Path, host: str) -> TlsFiles:
    """The files `issue_host` wrote for `host` in `directory`, checked to exist."""
    directory = Path(directory)
    files = TlsFiles(directory / AUTHORITY_CERTIFICATE, directory / f"{host}.pem", directory / f"{host}.key")
    missing = [str(path) for path in (files.authority, files.certificate, files.key) if not path.is_file()]
    if missing:
        raise CertificateError(f"no certificate for host {host!r}: missing {', '.join(missing)} "
                               f"(make them with 'iotad certs init {directory}' and "
                               f"'iotad certs host {host} --dir {directory}')")
    return files


def from_env() -> TlsFiles | None:
    """This process's certificates (`IOTAD_CERTS` folder, `IOTAD_CERTS_HOST` name), or None when
    they are not set. Raises `CertificateError` when they are set and the files are missing."""
    directory, host = os.environ.get(ENV_DIR), os.environ.get(ENV_HOST)
    if not directory:
        return None
    if not host:
        raise CertificateError(f"{ENV_DIR} is set but {ENV_HOST} (this host's name) is not")
    return host_files(directory, host)


def use(directory: str | Path, host: str) -> TlsFiles:
    """Check `host`'s certificates in `directory`, then make them this process's and its
    children's (the node hosts, the recorder and tools a launcher starts open their sessions with
    them)."""
    files = host_files(directory, host)
    os.environ[ENV_DIR], os.environ[ENV_HOST] = str(Path(directory).resolve()), host
    return files


def authority_name(system: str) -> str:
    """The common name of system `system`'s authority: two systems' authorities, and so the issuers
    of their hosts' certificates, read differently (`iotad certs show`)."""
    return f"{system} certificate authority"


def init_authority(directory: str | Path, name: str = "iotad", days: int = 3650, force: bool = False) -> Path:
    """Make a certificate authority for system `name` in `directory` (ca.pem, and ca.key readable by
    its owner only). Refuses to replace one unless `force`: every host certificate it signed would
    stop working."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    directory = Path(directory)
    certificate_path = directory / AUTHORITY_CERTIFICATE
    if certificate_path.exists() and not force:
        raise CertificateError(f"{certificate_path} exists: a new authority would invalidate every host "
                               "certificate it signed (use --force to replace it)")
    directory.mkdir(parents=True, exist_ok=True)
    key = ec.generate_private_key(ec.SECP256R1())
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, authority_name(name))])
    now = datetime.datetime.now(datetime.timezone.utc)
    certificate = (
        x509.CertificateBuilder()
        .subject_name(subject).issuer_name(subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))  # a host whose clock is a little behind
        .not_valid_after(now + datetime.timedelta(days=days))
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(x509.KeyUsage(digital_signature=True, key_cert_sign=True, crl_sign=True,
                                     content_commitment=False, key_encipherment=False, data_encipherment=False,
                                     key_agreement=False, encipher_only=False, decipher_only=False), critical=True)
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    _write_key(directory / AUTHORITY_KEY, key)
    certificate_path.write_bytes(_pem(certificate))
    return certificate_path


def issue_host(directory: str | Path, host: str, addresses: list[str] = (), days: int = 825,
               force: bool = False) -> TlsFiles:
    """Sign a certificate for `host` with the authority in `directory`: HOST.pem and HOST.key.
    `addresses` (IP addresses or DNS names the host is reached at) go into its subject
    alternative names, with the host name itself."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    directory = Path(directory)
    if not _HOST_NAME.match(host):
        raise CertificateError(f"host name {host!r}: use letters, digits, '.', '_' or '-' (at most 63), "
                               "as in the system file's [hosts.NAME]")
    try:
        authority = x509.load_pem_x509_certificate((directory / AUTHORITY_CERTIFICATE).read_bytes())
        authority_key = serialization.load_pem_private_key((directory / AUTHORITY_KEY).read_bytes(), None)
    except FileNotFoundError:
        raise CertificateError(f"no certificate authority in {directory} (make one with 'iotad certs init {directory}')") from None
    except ValueError as exc:
        raise CertificateError(f"the authority in {directory} cannot be read: {exc}") from None
    files = TlsFiles(directory / AUTHORITY_CERTIFICATE, directory / f"{host}.pem", directory / f"{host}.key")
    if files.certificate.exists() and not force:
        raise CertificateError(f"{files.certificate} exists (use --force to issue a new one)")
    names: list[x509.GeneralName] = [x509.DNSName(host)]
    for address in addresses:
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(address)))
        except ValueError:
            if not re.match(r"^[A-Za-z0-9.-]+$", address):
                raise CertificateError(f"address {address!r} is neither an IP address nor a DNS name") from None
            names.append(x509.DNSName(address))
    key = ec.generate_private_key(ec.SECP256R1())
    now = datetime.datetime.now(datetime.timezone.utc)
    certificate = (
        x509.CertificateBuilder()
        .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, host)]))
        .issuer_name(authority.subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))
        .not_valid_after(now + datetime.timedelta(days=days))
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(x509.SubjectAlternativeName(names), critical=False)
        .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]),
                       critical=False)
        .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(authority_key.public_key()), critical=False)
        .sign(authority_key, hashes.SHA256())
    )
    _write_key(files.key, key)
    files.certificate.write_bytes(_pem(certificate))
    return files


def describe(path: str | Path) -> str:
    """One line about a certificate: subject, names, issuer with its fingerprint, and expiry
    (`iotad certs show`)."""
    from cryptography import x509
    certificate = x509.load_pem_x509_certificate(Path(path).read_bytes())
    try:
        alternative = certificate.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
        names = ", ".join(str(name.value) for name in alternative)
    except x509.ExtensionNotFound:
        names = "-"
    return (f"{Path(path).name}: {certificate.subject.rfc4514_string()}; names {names}; "
            f"issued by {certificate.issuer.rfc4514_string()} (issuer fingerprint "
            f"{issuer_fingerprint(certificate, Path(path).with_name(AUTHORITY_CERTIFICATE))}); "
            f"valid until {certificate.not_valid_after_utc:%Y-%m-%d}")


def issuer_fingerprint(certificate, authority: Path | None = None) -> str:
    """The fingerprint of the key that signed `certificate`: SHA-256 of the issuer's public key
    (SubjectPublicKeyInfo, DER), in hex pairs. Two authorities of the same name differ here. Taken
    from the certificate that signed it where it lies beside (`ca.pem`), else from its own key for a
    self-signed one; otherwise the authority key identifier the certificate carries (SHA-1 of the
    issuer's key, RFC 5280), marked as such. `authority`: the certificate that may have signed it."""
    from cryptography import x509
    from cryptography.exceptions import InvalidSignature
    from cryptography.hazmat.primitives import hashes, serialization

    def of_key(public_key) -> str:
        digest = hashes.Hash(hashes.SHA256())
        digest.update(public_key.public_bytes(serialization.Encoding.DER,
                                              serialization.PublicFormat.SubjectPublicKeyInfo))
        return "sha256 " + digest.finalize().hex(":").upper()

    if certificate.issuer == certificate.subject:
        return of_key(certificate.public_key())
    if authority is not None and authority.is_file():
        try:
            issuer = x509.load_pem_x509_certificate(authority.read_bytes())
            certificate.verify_directly_issued_by(issuer)  # the one beside signed it, not only shares its name
            return of_key(issuer.public_key())
        except (ValueError, TypeError, InvalidSignature):
            pass
    try:
        identifier = certificate.extensions.get_extension_for_class(x509.AuthorityKeyIdentifier).value.key_identifier
    except x509.ExtensionNotFound:
        identifier = None
    return "sha1 key id " + identifier.hex(":").upper() if identifier else "unknown"


def _pem(certificate) -> bytes:
    from cryptography.hazmat.primitives import serialization
    return certificate.public_bytes(serialization.Encoding.PEM)


def _write_key(path: Path, key) -> None:
    from cryptography.hazmat.primitives import serialization
    data = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())
    # created 0600 from the start: a key must never be readable by others, even for an instant
    descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(descriptor, "wb") as handle:
        handle.write(data)
    os.chmod(path, 0o600)
