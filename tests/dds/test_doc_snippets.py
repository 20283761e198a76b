"""Every fenced ```python block in README.md and docs/ runs as written against the node.

Each block is run by this venv's Python as a script of its own (a fresh process, as a user pastes
it into a file), with a node serving the embedded default arm as /spatial_dynamics on this run's
ROS_DOMAIN_ID. A block names the repository's files by their path from its root
(`config/models/default_arm.urdf`): the script's directory links to the repository's `config/`.
A block passes when it exits 0 within 60 s; a block must therefore fail loudly (raise, exit
non-zero) when what it shows does not work. None is skipped.
"""

import re
import subprocess
import sys
from pathlib import Path

import pytest

import sd_dds_support as sd

FENCE = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL)


def python_blocks():
    blocks = []
    for doc in [sd.REPO / "README.md", *sorted((sd.REPO / "docs").rglob("*.md"))]:
        text = doc.read_text(encoding="utf-8")
        for m in FENCE.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            blocks.append(pytest.param(m.group(1), id=f"{doc.relative_to(sd.REPO)}:{line}"))
    return blocks


def test_the_documents_have_python_blocks():
    assert python_blocks(), "no ```python block in README.md or docs/: this test checks nothing"


@pytest.mark.parametrize("code", python_blocks())
def test_python_block_runs_against_the_node(code, arm, tmp_path):
    script = tmp_path / "block.py"
    (tmp_path / "config").symlink_to(sd.REPO / "config")
    script.write_text(code)
    try:
        out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=60,
                             stdin=subprocess.DEVNULL, cwd=tmp_path)
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f"the block did not finish within 60 s:\n{code}\n--- output ---\n{exc.stdout or ''}{exc.stderr or ''}")
    assert out.returncode == 0, f"the block failed ({out.returncode}):\n{code}\n--- stdout ---\n{out.stdout}\n--- stderr ---\n{out.stderr}"
