"""The onboard side runs with the core dependencies only (no PC extras on the Raspberry Pi)."""

import subprocess
import sys

PC_ONLY = ["pinocchio", "coal", "ompl", "toppra", "mujoco", "matplotlib", "scipy", "dask",
           "distributed", "py_trees"]

SCRIPT = f"""
import sys
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in {PC_ONLY!r}:
            raise ImportError('blocked PC-only package: ' + name)
sys.meta_path.insert(0, Block())
from articutool.spec import load_spec
from articutool.tool.runtime import ToolRuntime
from articutool.tool.drivers import make_drivers
from articutool.tool.drivers.sim import SimWrist
from articutool.link.server import ToolServer
from articutool.link.client import ArticutoolClient
from articutool.link.recording import McapRecorder, RecordingTransport
from articutool.cli import build_parser
spec = load_spec()
sim = SimWrist(spec, seed=0)
rt = ToolRuntime(spec, *make_drivers(spec, 'sim', sim=sim), clock=sim.clock)
with rt:
    for _ in range(50):
        sim.step(spec.wrist.period)
        rt.tick(now=sim.time, dt=spec.wrist.period)
    print(rt.set_mode(1))
build_parser()
print('core ok')
"""


def test_tool_and_link_import_and_run_without_pc_packages():
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert "(True, 'LEVELING" in out.stdout
    assert "core ok" in out.stdout
