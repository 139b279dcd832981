"""The link config: every field's bad value is refused naming the field, what it must be (its
allowed range or form) and the value given; a file in the documented TOML format loads."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from articutool.link.config import ConfigError, LinkConfig, load_config

NAME = "1-63 characters from a-z"
ENDPOINT = "'<protocol>/<host>:<port>'"
PAIRED_FILE = "a readable file (from articutool pair)"

# field, a bad value, what the refusal names (besides the field and the value)
BAD = [
    ("mode", "router", "'peer' or 'client'"),
    ("listen", "tcp/127.0.0.1:7447", "a list of zenoh endpoints"),
    ("listen", ["tcp/127.0.0.1:99999"], ENDPOINT),
    ("connect", {"tcp/127.0.0.1:7447"}, "a list of zenoh endpoints"),
    ("connect", [5], ENDPOINT),
    ("multicast_scouting", "yes", "true or false"),
    ("domain_id", 233, "an integer in [0, 232]"),
    ("domain_id", True, "an integer in [0, 232]"),
    ("domain_id", 1.0, "an integer in [0, 232]"),
    ("namespace", "/articutool/*", "e.g. '/articutool'"),
    ("type_hash_in_keys", 1, "true or false"),
    ("heartbeat_period", 0, "a number of seconds in (0, 10]"),
    ("tool_timeout", 3601, "a number of seconds in (0, 3600]"),
    ("client_timeout", math.nan, "a number of seconds in (0, 3600]"),
    ("link_loss_policy", "panic", "'continue' or 'cancel'"),
    ("call_timeout", math.inf, "a number of seconds in (0, 3600]"),
    ("publish_rate_hz", 1001, "(0, 1000]"),
    ("publish_rate_hz", True, "(0, 1000]"),
    ("reconnect_period", 1e308, "a number of seconds in (0, 60]"),
    ("reconnect_period", "0.2", "a number of seconds in (0, 60]"),
    ("extra", [1], "a table of zenoh settings"),
    ("tool_id", "a/b", NAME),
    ("identity", "", NAME),
    ("tls_root_ca", "missing-ca.pem", PAIRED_FILE),
    ("tls_certificate", "missing-cert.pem", PAIRED_FILE),
    ("tls_private_key", "missing-key.pem", PAIRED_FILE),
    ("require_paired", "yes", "true or false"),
    ("peers", "pc-1", "a list of device names"),
    ("peers", ["pc 1"], NAME),
    ("auth_window", 0, "in (0, 3600] seconds"),
    ("max_trajectory_bytes", 63, "an integer in [64, 1073741824]"),
    ("max_request_bytes", 1 << 21, "an integer in [64, 1048576]"),
    ("inbox_size", 4097, "an integer in [1, 4096]"),
    ("inbox_size", 2.0, "an integer in [1, 4096]"),
    ("max_rate_hz", 0.5, "in [1, 100000] messages/s"),
    ("audit_log", 5, "a file path"),
]


def test_every_field_has_a_bad_value_case() -> None:
    assert {f for f, _, _ in BAD} == set(LinkConfig.model_fields)


@pytest.mark.parametrize("field,value,allowed", BAD,
                         ids=[f"{f}={v!r}" for f, v, _ in BAD])
def test_a_bad_value_is_refused_naming_the_field_and_what_it_must_be(field, value, allowed):
    with pytest.raises(ConfigError) as err:
        LinkConfig(**{field: value})
    msg = str(err.value)
    shown = repr(value[0]) if field in ("listen", "connect", "peers") and isinstance(
        value, list) else repr(value)
    assert field in msg and allowed in msg and shown in msg, msg
    assert "pydantic" not in msg and "Input should" not in msg, msg


def test_a_file_names_itself_and_every_bad_setting(tmp_path: Path) -> None:
    f = tmp_path / "link.toml"
    f.write_text('[link]\ntool_timeout = -1\ninbox_size = 0\nlistne = []\n')
    with pytest.raises(ConfigError) as err:
        load_config(f)
    msg = str(err.value)
    assert msg.startswith(f"{f}: "), msg
    for words in ("unknown setting(s) ['listne']", "tool_timeout must be a number of seconds "
                  "in (0, 3600]; got -1", "inbox_size must be an integer in [1, 4096]; got 0"):
        assert words in msg, msg


def test_cross_field_rules_name_both_fields() -> None:
    with pytest.raises(ConfigError, match="heartbeat_period must be shorter than tool_timeout"):
        LinkConfig(heartbeat_period=1.0, tool_timeout=1.0)
    with pytest.raises(ConfigError, match="require_paired = true needs tls_root_ca"):
        LinkConfig(require_paired=True)


def test_the_documented_toml_format_loads_every_field(tmp_path: Path) -> None:
    for name in ("ca.pem", "cert.pem", "key.pem"):
        (tmp_path / name).write_text("pem")
    f = tmp_path / "link.toml"
    f.write_text("""
[link]
mode = "client"
listen = ["tls/0.0.0.0:7447"]
connect = ["unixsock-stream/tmp/z.sock"]
multicast_scouting = true
domain_id = 232
namespace = "/lab_2/articutool"
type_hash_in_keys = false
heartbeat_period = 0.05
tool_timeout = 2
client_timeout = 3.5
link_loss_policy = "cancel"
call_timeout = 4
publish_rate_hz = 100
reconnect_period = 1
tool_id = "wrist-1"
identity = "pc-1"
tls_root_ca = "ca.pem"
tls_certificate = "cert.pem"
tls_private_key = "key.pem"
require_paired = true
peers = ["pc-1", "pc-2"]
auth_window = 10
max_trajectory_bytes = 65536
max_request_bytes = 1024
inbox_size = 4
max_rate_hz = 50
audit_log = "audit.jsonl"

[link.extra]
"transport/unicast/max_links" = 2
"scouting/gossip" = {enabled = false}
""")
    c = load_config(f)
    assert c == LinkConfig(
        mode="client", listen=("tls/0.0.0.0:7447",), connect=("unixsock-stream/tmp/z.sock",),
        multicast_scouting=True, domain_id=232, namespace="/lab_2/articutool",
        type_hash_in_keys=False, heartbeat_period=0.05, tool_timeout=2.0, client_timeout=3.5,
        link_loss_policy="cancel", call_timeout=4.0, publish_rate_hz=100.0,
        reconnect_period=1.0, tool_id="wrist-1", identity="pc-1",
        tls_root_ca=str(tmp_path / "ca.pem"), tls_certificate=str(tmp_path / "cert.pem"),
        tls_private_key=str(tmp_path / "key.pem"), require_paired=True,
        peers=("pc-1", "pc-2"), auth_window=10.0, max_trajectory_bytes=65536,
        max_request_bytes=1024, inbox_size=4, max_rate_hz=50.0,
        audit_log=str(tmp_path / "audit.jsonl"),
        extra={"transport/unicast/max_links": 2, "scouting/gossip": {"enabled": False}})
    assert c.paired and c.requires_pairing
    assert c.replace(inbox_size=5).inbox_size == 5 and c.inbox_size == 4
    with pytest.raises(ConfigError, match="inbox_size"):
        c.replace(inbox_size=0)
