"""The examples in examples/python run (small sizes) and do what they say."""

import os
import pathlib
import subprocess
import sys

import pytest

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples" / "python"


def run(script, *args, cwd=None):
    env = dict(os.environ)  # PYTHONPATH: the build tree's package, as ctest sets it
    out = subprocess.run([sys.executable, str(EXAMPLES / script), *args], capture_output=True, text=True,
                         timeout=300, env=env, cwd=cwd)
    assert out.returncode == 0, out.stdout + out.stderr
    return out.stdout


def test_random_pairs():
    assert "match a brute force" in run("random_pairs.py", "--objects", "20000")


def test_granular_pile(tmp_path):
    png = tmp_path / "pile.png"
    stdout = run("granular_pile.py", "--grains", "600", "--steps", "300", "--out", str(png))
    assert "wrote" in stdout
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_contact_events():
    stdout = run("contact_events.py", "--objects", "5000", "--frames", "4")
    assert stdout.count("began") == 4


@pytest.mark.parametrize("script", ["random_pairs.py", "granular_pile.py", "contact_events.py"])
def test_help(script):
    assert "usage" in run(script, "--help")
