"""The examples under examples/python run and say what they should."""

import subprocess
import sys

from conftest import ROOT


def run(name, *args):
    return subprocess.run(
        [sys.executable, str(ROOT / "examples" / "python" / name), *map(str, args)],
        cwd=ROOT, capture_output=True, text=True, check=True, timeout=600,
    ).stdout


def test_volume_to_mesh(tmp_path):
    out = run("volume_to_mesh.py", tmp_path / "v.ply")
    assert "components: [(True, 0)]" in out
    assert (tmp_path / "v.ply").stat().st_size > 0


def test_scenes_and_fields(tmp_path):
    out = run("scenes_and_fields.py", tmp_path / "saucer.glb")
    assert "genus 1" in out and "region pairs: [(1, 2), (1, 3), (2, 3)]" in out
    assert (tmp_path / "saucer.glb").stat().st_size > 0
