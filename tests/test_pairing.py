"""``articutool pair`` and the pairing config: safe files, never overwritten,
bad input exits 2 naming the field; signatures verify only for the pairing CA's devices."""

from __future__ import annotations

import stat
import time
from pathlib import Path

import pytest

from articutool.cli import main
from articutool.link.auth import AuthError, Signer, Verifier, claim
from articutool.link.config import ConfigError, LinkConfig, load_config


def _mode(p: Path) -> int:
    return stat.S_IMODE(p.stat().st_mode)


def test_pair_writes_keys_0600_and_never_overwrites(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture) -> None:
    d = tmp_path / "pairing"
    assert main(["pair", "--dir", str(d), "--tool", "wrist-1", "--pc", "pc-1"]) == 0
    for key in (d / "ca" / "ca.key", d / "wrist-1" / "key.pem", d / "pc-1" / "key.pem"):
        assert _mode(key) == 0o600, key
    for folder in (d / "ca", d / "wrist-1", d / "pc-1"):
        assert _mode(folder) == 0o700
    before = {p: p.read_bytes() for p in d.rglob("*") if p.is_file()}
    capsys.readouterr()
    # Pairing the same PC again: refused, naming the file, nothing changed.
    assert main(["pair", "--dir", str(d), "--tool", "wrist-1", "--pc", "pc-1"]) == 2
    err = capsys.readouterr().err
    assert f"{d / 'pc-1' / 'cert.pem'} exists" in err and "never overwritten" in err
    assert {p: p.read_bytes() for p in d.rglob("*") if p.is_file()} == before
    # A new PC for the same tool: the CA and the tool are kept, the PC is added.
    assert main(["pair", "--dir", str(d), "--tool", "wrist-1", "--pc", "pc-2"]) == 0
    assert all(p.read_bytes() == b for p, b in before.items())
    assert _mode(d / "pc-2" / "key.pem") == 0o600
    # Bad names and numbers: exit 2 naming the field.
    assert main(["pair", "--dir", str(d), "--tool", "wrist 1", "--pc", "pc-3"]) == 2
    assert "--tool must be" in capsys.readouterr().err
    assert main(["pair", "--dir", str(tmp_path / "x"), "--tool", "t", "--pc", "p",
                 "--days", "0"]) == 2
    assert "--days must be an integer in [1, 36500]" in capsys.readouterr().err


def test_link_configs_written_by_pair_load_and_bad_tls_settings_name_the_field(
        tmp_path: Path) -> None:
    main(["pair", "--dir", str(tmp_path), "--tool", "wrist-1", "--pc", "pc-1"])
    tool = load_config(tmp_path / "wrist-1" / "link.toml")
    pc = load_config(tmp_path / "pc-1" / "link.toml")
    assert tool.paired and tool.requires_pairing and tool.tool_id == "wrist-1"
    assert tool.endpoints("tool")[0] == ("tls/0.0.0.0:7447",)
    assert pc.identity == "pc-1" and pc.tool_id == "wrist-1"
    assert Path(pc.tls_private_key).is_absolute()  # relative to the config file
    with pytest.raises(ConfigError, match="tls_private_key"):
        LinkConfig(tls_root_ca=pc.tls_root_ca, tls_certificate=pc.tls_certificate)
    with pytest.raises(ConfigError, match="tls_root_ca must be a readable file"):
        LinkConfig(tls_root_ca=str(tmp_path / "nope.pem"), tls_certificate=pc.tls_certificate,
                   tls_private_key=pc.tls_private_key)
    with pytest.raises(ConfigError, match="require_paired = true needs"):
        LinkConfig(require_paired=True)
    with pytest.raises(ConfigError, match="tool_id must be"):
        LinkConfig(tool_id="a/b")


def test_signatures_verify_for_the_pairing_ca_only(tmp_path: Path) -> None:
    main(["pair", "--dir", str(tmp_path / "a"), "--tool", "wrist-1", "--pc", "pc-1"])
    main(["pair", "--dir", str(tmp_path / "b"), "--tool", "wrist-1", "--pc", "pc-1"])
    ours = Signer(tmp_path / "a" / "pc-1" / "cert.pem", tmp_path / "a" / "pc-1" / "key.pem")
    theirs = Signer(tmp_path / "b" / "pc-1" / "cert.pem", tmp_path / "b" / "pc-1" / "key.pem")
    v = Verifier(tmp_path / "a" / "ca" / "ca.pem", window=5.0)
    att = ours.attachment("/articutool/wrist-1/set_orientation_control", b"payload")
    s = v.verify("/articutool/wrist-1/set_orientation_control", b"payload", att)
    assert s.verified and s.identity == "pc-1" and s.role == "pc"
    with pytest.raises(AuthError, match="replayed"):
        v.verify("/articutool/wrist-1/set_orientation_control", b"payload", att)
    att = ours.attachment("/articutool/wrist-1/set_orientation_control", b"payload")
    with pytest.raises(AuthError, match="does not match"):  # another payload
        v.verify("/articutool/wrist-1/set_orientation_control", b"other", att)
    att = ours.attachment("/articutool/wrist-1/send_goal", b"payload")
    with pytest.raises(AuthError, match="does not match"):  # another endpoint
        v.verify("/articutool/wrist-1/set_orientation_control", b"payload", att)
    with pytest.raises(AuthError, match="pairing CA"):
        v.verify("k", b"p", theirs.attachment("k", b"p"))
    with pytest.raises(AuthError, match="unsigned claim"):
        v.verify("k", b"p", claim("pc-1"))
    with pytest.raises(AuthError, match="no signature"):
        v.verify("k", b"p", None)
    only = Verifier(tmp_path / "a" / "ca" / "ca.pem", peers=("pc-9",))
    with pytest.raises(AuthError, match="not among the paired peers"):
        only.verify("k", b"p", ours.attachment("k", b"p"))
    old = Verifier(tmp_path / "a" / "ca" / "ca.pem", window=1.0)
    att = ours.attachment("k", b"p")
    time.sleep(1.2)
    with pytest.raises(AuthError, match="timestamp"):
        old.verify("k", b"p", att)


def test_an_unpaired_tool_refuses_a_plain_network_listener(capsys: pytest.CaptureFixture
                                                           ) -> None:
    assert main(["tool", "--listen", "tcp/0.0.0.0:7447", "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert "listen endpoint tcp/0.0.0.0:7447" in err and "articutool pair" in err


@pytest.mark.parametrize("setting", [
    'listen = ["tcp/0.0.0.0:7447"]',
    'connect = ["tcp/192.0.2.7:7447"]',
    'listen = ["tcp/127.attacker.invalid:7447"]',  # spelled like loopback, does not resolve
    'listen = ["ws/[::]:7447"]',
    "multicast_scouting = true",
    '[extra]\n"listen/endpoints" = ["tcp/0.0.0.0:7447"]',
    '[extra]\n"mode" = "router"\n"listen/endpoints" = {router = ["tcp/0.0.0.0:7447"]}',
    '[extra]\n"listen/endpoints" = {peer = ["udp/0.0.0.0:7447"]}',
    '[extra]\n"listen" = {}',  # zenoh's default then: every interface
    '[extra]\n"connect" = {endpoints = ["tcp/192.0.2.7:7447"]}',
    '[extra]\n"scouting/multicast/enabled" = true',
])
def test_every_way_to_expose_an_unpaired_tool_is_refused(
        setting: str, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """Every setting that opens the tool to the network counts, however it is spelled."""
    f = tmp_path / "link.toml"
    f.write_text(setting + "\n")
    assert main(["tool", "--link-config", str(f), "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert "accepts unsigned commands" in err and "--insecure-listen" in err, err


def test_an_extra_zenoh_setting_zenoh_refuses_exits_2_naming_it(
        tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    f = tmp_path / "link.toml"
    f.write_text('[extra]\n"nonsense/key" = 1\n')
    assert main(["tool", "--link-config", str(f), "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert "extra['nonsense/key']" in err and "Traceback" not in err, err


def test_loopback_unix_sockets_and_mutual_tls_are_not_exposure(tmp_path: Path) -> None:
    from articutool.link.zenoh_transport import exposure

    for ok in ("tcp/127.0.0.1:7447", "tcp/localhost:7447", "tcp/[::1]:7447",
               "udp/127.0.0.2:7447#iface=lo", f"unixsock-stream/{tmp_path / 's'}"):
        assert exposure(LinkConfig(listen=(ok,))) == [], ok
    assert exposure(LinkConfig()) == []  # the default
    main(["pair", "--dir", str(tmp_path / "p"), "--tool", "wrist-1", "--pc", "pc-1"])
    tool = load_config(tmp_path / "p" / "wrist-1" / "link.toml")
    assert exposure(tool) == []  # tls/0.0.0.0 with mutual TLS by the pairing CA
    no_mtls = tool.replace(extra={"transport/link/tls/enable_mtls": False})
    assert exposure(no_mtls) == ["listen endpoint tls/0.0.0.0:7447"]
