"""``articutool pair``: a small certificate authority and one certificate per device.

Pairing makes the tool and the PC trust each other and nobody else. It writes::

    <dir>/ca/ca.pem, ca.key            the pairing CA (keep ca.key off the tool)
    <dir>/<device>/cert.pem, key.pem   the device's certificate (CN = device name) and key
    <dir>/<device>/ca.pem              the CA certificate the device trusts
    <dir>/<device>/link.toml           the device's link config (mutual TLS, its identity)

Keys are ECDSA P-256, written with mode 0600 in 0700 directories; existing files are never
overwritten (a second ``pair`` with the same ``--dir`` reuses the CA and adds devices, and
refuses, naming the file, a device that exists). A device's certificate carries its role
(``OU=tool`` or ``OU=pc``) and is valid for ``--days``. A PC is added to a tool paired before
by running ``pair`` again with the same ``--dir`` and ``--tool`` (the tool's files are kept;
the tool accepts any PC the CA signed unless its config lists ``peers``).

The same certificates serve twice: Zenoh's TLS transport with ``enable_mtls`` (encryption,
and no session at all for a peer without a certificate from this CA), and the link's own
signatures (``articutool.link.auth``): every command, trajectory and heartbeat carries the
sender's certificate and an ECDSA signature, which the tool checks against the CA before
acting, counting refusals, and which names the commander for the lease. Zenoh's own
access-control rules (``cert_common_names``) could refuse non-paired subjects too, but they
act silently inside Zenoh (nothing to count), do not apply on a plain TCP listener, and
cannot tell one paired PC from another for the command lease, so the check is ours.

Name verification on connect is off (``verify_name_on_connect``): the PC does not know the
Pi's address when pairing; the CA signature is what the PC checks, and only paired devices
hold CA-signed certificates.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import ipaddress
import os
import re
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

__all__ = ["NAME_FORM", "Paired", "PairingError", "check_name", "check_tool_host", "pair"]

NAME_FORM = "1-63 characters from a-z, A-Z, 0-9, '-' and '_', starting with a letter or digit"
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,62}$")
ORG = "articutool"


class PairingError(ValueError):
    """Pairing cannot proceed (the message names the file or field)."""


@dataclass(frozen=True)
class Paired:
    """What :func:`pair` wrote."""

    ca_created: bool
    files: tuple[Path, ...]
    tool_kept: bool = False  # the tool was paired before: only PCs were added


def check_name(name: object, field: str) -> str:
    """A device name (certificate CN, key-expression segment): ``NAME_FORM``."""
    if not isinstance(name, str) or not _NAME.match(name):
        raise PairingError(f"{field} must be {NAME_FORM}; got {name!r}")
    return name


def _write(path: Path, data: bytes, mode: int) -> Path:
    """Create ``path`` with ``mode`` (never overwrite; exclusive create, no umask widening)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, mode)
    try:
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view):]
        os.fchmod(fd, mode)
    except BaseException:
        path.unlink(missing_ok=True)  # created here: a partial file is not left behind
        raise
    finally:
        os.close(fd)
    return path


def _mkdir(path: Path, created: list[Path]) -> None:
    """Create ``path`` (0700) and its missing parents, appending each one made to
    ``created`` (so a failed pairing can remove them again)."""
    missing = [p for p in (path, *path.parents) if not p.exists()]
    path.mkdir(mode=0o700, parents=True, exist_ok=True)
    created.extend(reversed(missing))
    os.chmod(path, 0o700)


# The folder that holds the CA: no device may be named so (its key would land beside the
# CA's).
CA_FOLDER = "ca"
_LABEL = re.compile(r"^[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?$")
TOOL_HOST_FORM = ("a host name (dot-separated labels of letters, digits and '-', at most 253 "
                  "characters) or an IPv4 or IPv6 address")


def check_tool_host(host: object) -> str:
    """``--tool-host`` as it goes into a PC's endpoint ``tls/<host>:<port>`` (an IPv6 address
    in brackets)."""
    if isinstance(host, str):
        try:
            ip = ipaddress.ip_address(host.removeprefix("[").removesuffix("]"))
        except ValueError:
            labels = host.removesuffix(".").split(".")
            if len(host) <= 253 and all(_LABEL.match(x) for x in labels):
                return host
        else:
            return f"[{ip}]" if ip.version == 6 else str(ip)
    raise PairingError(f"--tool-host must be {TOOL_HOST_FORM}; got {host!r}")


def _role(cert_path: Path) -> str | None:
    """The role (``OU``) in a device certificate, None if unreadable."""
    try:
        cert = x509.load_pem_x509_certificate(cert_path.read_bytes())
        ou = cert.subject.get_attributes_for_oid(NameOID.ORGANIZATIONAL_UNIT_NAME)
    except (OSError, ValueError):
        return None
    return str(ou[0].value) if ou else None


def _key_pem(key: ec.EllipticCurvePrivateKey) -> bytes:
    return key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())


def _new_ca(days: int) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey]:
    key = ec.generate_private_key(ec.SECP256R1())
    now = dt.datetime.now(dt.UTC)
    name = x509.Name([x509.NameAttribute(NameOID.ORGANIZATION_NAME, ORG),
                      x509.NameAttribute(NameOID.COMMON_NAME,
                                         f"articutool pairing CA {os.urandom(4).hex()}")])
    cert = (x509.CertificateBuilder().subject_name(name).issuer_name(name)
            .public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(minutes=5))
            .not_valid_after(now + dt.timedelta(days=days))
            .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
            .add_extension(x509.KeyUsage(digital_signature=False, content_commitment=False,
                                         key_encipherment=False, data_encipherment=False,
                                         key_agreement=False, key_cert_sign=True,
                                         crl_sign=True, encipher_only=False,
                                         decipher_only=False), critical=True)
            .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()),
                           critical=False)
            .sign(key, hashes.SHA256()))
    return cert, key


def _device_cert(name: str, role: str, ca: x509.Certificate, ca_key: ec.EllipticCurvePrivateKey,
                 days: int) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey]:
    key = ec.generate_private_key(ec.SECP256R1())
    now = dt.datetime.now(dt.UTC)
    subject = x509.Name([x509.NameAttribute(NameOID.ORGANIZATION_NAME, ORG),
                         x509.NameAttribute(NameOID.ORGANIZATIONAL_UNIT_NAME, role),
                         x509.NameAttribute(NameOID.COMMON_NAME, name)])
    cert = (x509.CertificateBuilder().subject_name(subject).issuer_name(ca.subject)
            .public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(minutes=5))
            .not_valid_after(now + dt.timedelta(days=days))
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH,
                                                  ExtendedKeyUsageOID.CLIENT_AUTH]),
                           critical=False)
            .add_extension(x509.SubjectAlternativeName([x509.DNSName(name)]), critical=False)
            .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(
                ca_key.public_key()), critical=False)
            .sign(ca_key, hashes.SHA256()))
    return cert, key


def _link_toml(role: str, name: str, tool: str, port: int, tool_host: str) -> str:
    tls = ('tls_root_ca = "ca.pem"\ntls_certificate = "cert.pem"\n'
           'tls_private_key = "key.pem"\n')
    if role == "tool":
        where = (f'listen = ["tls/0.0.0.0:{port}"]  # every interface, mutual TLS only\n'
                 'connect = []\naudit_log = "audit.jsonl"  # lease transitions, take-overs\n')
    else:
        where = f'connect = ["tls/{tool_host}:{port}"]  # the tool\'s address\nlisten = []\n'
    return (f"# articutool link config for {role} {name!r} (written by articutool pair).\n"
            "# Paths are relative to this file.\n"
            f'identity = "{name}"\ntool_id = "{tool}"\n{where}{tls}')


def pair(directory: str | Path, tool: str, pcs: list[str], days: int = 3650, port: int = 7447,
         tool_host: str = "raspberrypi.local") -> Paired:
    """Create (or reuse) the CA under ``directory`` and a certificate for ``tool`` and each PC.

    Raises PairingError naming the first file that already exists (nothing is written then)
    or a bad name/number.
    """
    check_name(tool, "--tool")
    for i, pc in enumerate(pcs):
        check_name(pc, f"--pc[{i}]")
    names = [tool, *pcs]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise PairingError(f"device names must be distinct; {sorted(dup)} given twice")
    if not isinstance(days, int) or not 1 <= days <= 36500:
        raise PairingError(f"--days must be an integer in [1, 36500]; got {days!r}")
    if not isinstance(port, int) or not 1 <= port <= 65535:
        raise PairingError(f"--port must be an integer in [1, 65535]; got {port!r}")
    tool_host = check_tool_host(tool_host)
    for field_name, name in (("--tool", tool), *((f"--pc[{i}]", pc) for i, pc in enumerate(pcs))):
        if name.lower() == CA_FOLDER:
            raise PairingError(f"{field_name} must not be {CA_FOLDER!r}: that folder holds the "
                               "pairing CA (choose another device name)")
    root = Path(directory)
    ca_dir = root / "ca"
    ca_pem, ca_key_path = ca_dir / "ca.pem", ca_dir / "ca.key"
    ca_exists = ca_pem.exists() or ca_key_path.exists()
    if ca_exists and not (ca_pem.exists() and ca_key_path.exists()):
        missing = ca_key_path if ca_pem.exists() else ca_pem
        raise PairingError(f"{missing} is missing but the rest of the CA exists; restore it or "
                           "pair into a new --dir")
    files = ("cert.pem", "key.pem", "ca.pem", "link.toml")
    # A tool paired before is kept as it is (adding a PC to it); anything else that exists
    # is refused before writing anything.
    keep_tool = ca_exists and all((root / tool / f).exists() for f in files)
    if keep_tool and _role(root / tool / "cert.pem") != "tool":
        raise PairingError(f"--tool {tool}: {root / tool / 'cert.pem'} is not a tool's "
                           "certificate (a PC's, or unreadable); name the tool paired in "
                           f"{root}")
    for name in names if not keep_tool else pcs:
        for f in files:
            if (root / name / f).exists():
                raise PairingError(f"{root / name / f} exists: never overwritten (pair the "
                                   "device under another name, or remove it first)")
    if ca_exists:
        try:
            ca = x509.load_pem_x509_certificate(ca_pem.read_bytes())
            ca_key = serialization.load_pem_private_key(ca_key_path.read_bytes(), None)
        except (OSError, ValueError) as err:
            raise PairingError(f"{ca_dir}: cannot read the existing CA: {err}") from None
        if not isinstance(ca_key, ec.EllipticCurvePrivateKey):
            raise PairingError(f"{ca_key_path}: not an EC private key")
    written: list[Path] = []
    created: list[Path] = []
    try:
        if not ca_exists:
            _mkdir(ca_dir, created)
            ca, ca_key = _new_ca(days)
            written.append(_write(ca_key_path, _key_pem(ca_key), 0o600))
            written.append(_write(ca_pem, ca.public_bytes(serialization.Encoding.PEM), 0o644))
        ca_bytes = ca.public_bytes(serialization.Encoding.PEM)
        for name in names if not keep_tool else pcs:
            role = "tool" if name == tool else "pc"
            cert, key = _device_cert(name, role, ca, ca_key, days)
            d = root / name
            _mkdir(d, created)
            written.append(_write(d / "key.pem", _key_pem(key), 0o600))
            written.append(_write(d / "cert.pem", cert.public_bytes(serialization.Encoding.PEM),
                                  0o644))
            written.append(_write(d / "ca.pem", ca_bytes, 0o644))
            written.append(_write(d / "link.toml",
                                  _link_toml(role, name, tool, port, tool_host).encode(), 0o644))
    except BaseException as err:
        # All or nothing: remove what this call wrote, newest first.
        for f in reversed(written):
            f.unlink(missing_ok=True)
        for d in reversed(created):
            with contextlib.suppress(OSError):
                d.rmdir()
        if isinstance(err, OSError):
            raise PairingError(f"cannot write {err.filename or root}: {err.strerror} "
                               "(nothing was kept)") from None
        raise
    return Paired(not ca_exists, tuple(written), keep_tool)
