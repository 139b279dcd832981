"""Can the ROS 2 wheels from PyPI run DDS-Security (SROS2)? A measurement, written as JSON.

Builds a complete SROS2-layout keystore with ``openssl`` (ECDSA P-256 identity and
permissions CAs, a signed governance document that requires authentication, encryption and
access control, an enclave with its certificate, key and signed permissions allowing
everything), then starts rclpy in a child process three ways and records what each does:

- ``plain``: no security variables (the control);
- ``enforce``: ``ROS_SECURITY_ENABLE=true``, ``ROS_SECURITY_STRATEGY=Enforce`` and the
  keystore: SROS2's own "refuse to run unsecured" setting;
- ``permissive``: the same with ``ROS_SECURITY_STRATEGY=Permissive``: what a user who set
  security up gets when it cannot be enforced.

For each: whether a node could be created, rcl's error text, and whether a second, plain
process (no keystore at all) on the same domain could see the node in the graph — the test of
whether security actually kept an outsider out. Also the strings the Fast DDS library
carries that say whether it was compiled with its security plugins. Writes::

    .venv/bin/python studies/ros2_dds_security.py --out studies/results/ros2_dds_security.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import random
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path
from typing import Any

ENCLAVE = "/articutool/ros2"

_GOVERNANCE = """<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
  <domain_access_rules>
    <domain_rule>
      <domains><id_range><min>0</min><max>232</max></id_range></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>SIGN</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
"""

_PERMISSIONS = """<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
  <permissions>
    <grant name="{enclave}">
      <subject_name>CN={enclave}</subject_name>
      <validity><not_before>2020-01-01T00:00:00</not_before>
        <not_after>2040-01-01T00:00:00</not_after></validity>
      <allow_rule>
        <domains><id_range><min>0</min><max>232</max></id_range></domains>
        <publish><topics><topic>*</topic></topics></publish>
        <subscribe><topics><topic>*</topic></topics></subscribe>
      </allow_rule>
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
"""


def _openssl(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True)


def make_keystore(root: Path) -> Path:
    """An SROS2-layout keystore under ``root`` with one enclave (``ENCLAVE``); returns it."""
    ks = root / "keystore"
    enc = ks / "enclaves" / ENCLAVE.strip("/")
    for d in (ks / "public", ks / "private", enc):
        d.mkdir(parents=True, exist_ok=True)
    priv, pub = ks / "private", ks / "public"
    for ca in ("identity_ca", "permissions_ca"):
        _openssl("ecparam", "-name", "prime256v1", "-genkey", "-noout", "-out",
                 f"{ca}.key.pem", cwd=priv)
        _openssl("req", "-new", "-x509", "-sha256", "-days", "3650", "-key",
                 f"{ca}.key.pem", "-subj", f"/CN=articutool_{ca}", "-out",
                 str(pub / f"{ca}.cert.pem"), cwd=priv)
    (ks / "enclaves" / "governance.xml").write_text(_GOVERNANCE)
    _openssl("smime", "-sign", "-text", "-in", "governance.xml", "-out", "governance.p7s",
             "-signer", str(pub / "permissions_ca.cert.pem"), "-inkey",
             str(priv / "permissions_ca.key.pem"), cwd=ks / "enclaves")
    _openssl("ecparam", "-name", "prime256v1", "-genkey", "-noout", "-out", "key.pem", cwd=enc)
    _openssl("req", "-new", "-sha256", "-key", "key.pem", "-subj",
             "/CN=" + ENCLAVE.replace("/", "\\/"),
             "-out", "req.pem", cwd=enc)
    _openssl("x509", "-req", "-sha256", "-days", "3650", "-in", "req.pem", "-CA",
             str(pub / "identity_ca.cert.pem"), "-CAkey", str(priv / "identity_ca.key.pem"),
             "-CAcreateserial", "-out", "cert.pem", cwd=enc)
    (enc / "permissions.xml").write_text(_PERMISSIONS.format(enclave=ENCLAVE))
    _openssl("smime", "-sign", "-text", "-in", "permissions.xml", "-out", "permissions.p7s",
             "-signer", str(pub / "permissions_ca.cert.pem"), "-inkey",
             str(priv / "permissions_ca.key.pem"), cwd=enc)
    for name in ("identity_ca.cert.pem", "permissions_ca.cert.pem"):
        (enc / name).write_bytes((pub / name).read_bytes())
    (enc / "governance.p7s").write_bytes((ks / "enclaves" / "governance.p7s").read_bytes())
    return ks


_CHILD = textwrap.dedent("""
    import json, sys, time
    import rclpy
    out = {"node_created": False, "error": ""}
    try:
        rclpy.init(args=["--ros-args", "--enclave", sys.argv[1]] if sys.argv[1] else [])
        node = rclpy.create_node("secured_probe")
        out["node_created"] = True
        print("UP", flush=True)
        time.sleep(float(sys.argv[2]))
        node.destroy_node()
        rclpy.shutdown()
    except Exception as err:
        out["error"] = f"{type(err).__name__}: {err}"
    print("RESULT " + json.dumps(out), flush=True)
""")

_OUTSIDER = textwrap.dedent("""
    import json, time
    import rclpy
    rclpy.init()
    node = rclpy.create_node("outsider")
    seen = False
    deadline = time.monotonic() + 8
    while time.monotonic() < deadline and not seen:
        rclpy.spin_once(node, timeout_sec=0.2)
        seen = "secured_probe" in node.get_node_names()
    print("SEEN " + json.dumps(seen), flush=True)
    node.destroy_node(); rclpy.shutdown()
""")


def _probe(env: dict[str, str], enclave: str) -> dict[str, Any]:
    child = subprocess.Popen([sys.executable, "-c", _CHILD, enclave, "12"], env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert child.stdout is not None
    first = child.stdout.readline()
    seen = None
    if first.startswith("UP"):
        plain = {k: v for k, v in env.items() if not k.startswith("ROS_SECURITY")}
        out = subprocess.run([sys.executable, "-c", _OUTSIDER], env=plain, text=True,
                             capture_output=True, timeout=60).stdout
        line = next((ln for ln in out.splitlines() if ln.startswith("SEEN ")), "SEEN null")
        seen = json.loads(line[5:])
    rest, err = child.communicate(timeout=60)
    text = first + rest
    line = next((ln for ln in text.splitlines() if ln.startswith("RESULT ")), None)
    res = json.loads(line[7:]) if line else {"node_created": False, "error": "no result"}
    res["outsider_saw_the_node"] = seen
    res["stderr_tail"] = err.strip().splitlines()[-6:]
    return res


def library_strings() -> dict[str, Any]:
    """Whether the Fast DDS library holds its builtin security plugins' names, and whether
    the rmw layer holds the message it gives when Fast DDS was built without them."""
    found: dict[str, Any] = {}
    probes = {"libfastdds.so": ["builtin.PKI-DH", "builtin.Access-Permissions",
                                "builtin.AES-GCM-GMAC"],
              "librmw_fastrtps_shared_cpp.so": [
                  "This Fast DDS version doesn't have the security libraries"]}
    for name, strings in probes.items():
        lib = Path(sys.prefix, "lib", name)
        if lib.exists():
            data = lib.resolve().read_bytes()
            found[lib.resolve().name] = {s: s.encode() in data for s in strings}
    return found


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="studies/results/ros2_dds_security.json")
    args = ap.parse_args()
    domain = random.Random(os.getpid()).randint(150, 220)
    base = {k: v for k, v in os.environ.items() if not k.startswith("ROS_SECURITY")}
    base.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
                RMW_IMPLEMENTATION="rmw_fastrtps_cpp")
    with tempfile.TemporaryDirectory(prefix="sros2-") as tmp:
        ks = make_keystore(Path(tmp))
        runs = {"plain": _probe(base, "")}
        for strategy in ("Enforce", "Permissive"):
            env = dict(base, ROS_SECURITY_ENABLE="true", ROS_SECURITY_STRATEGY=strategy,
                       ROS_SECURITY_KEYSTORE=str(ks))
            runs[strategy.lower()] = _probe(env, ENCLAVE)
    from importlib.metadata import version

    doc = {
        "question": "does the PyPI Fast DDS run DDS-Security (SROS2)?",
        "answer": ("yes" if runs["enforce"]["node_created"]
                   and runs["enforce"]["outsider_saw_the_node"] is False else "no"),
        "machine": {"python": sys.version.split()[0], "platform": platform.platform()},
        "versions": {p: version(p) for p in ("ros-rclpy", "ros-rmw-fastrtps-cpp",
                                             "ros-fastdds")},
        "fastdds_library": library_strings(),
        "runs": runs,
    }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(doc, indent=2) + "\n")
    print(json.dumps({k: doc[k] for k in ("answer", "fastdds_library")}, indent=1))
    for k, r in runs.items():
        print(k, {x: r[x] for x in ("node_created", "error", "outsider_saw_the_node")})
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
