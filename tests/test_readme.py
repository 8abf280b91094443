"""The README's promises: its two set-up commands come first, CI runs its test command, and its
Python snippet runs as printed."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _blocks(text: str, lang: str) -> list[str]:
    return re.findall(rf"^```{lang}\n(.*?)^```", text, flags=re.S | re.M)


def test_the_readme_starts_with_the_two_set_up_commands_and_ci_runs_the_test_command() -> None:
    text = README.read_text(encoding="utf-8")
    first = _blocks(text, "bash")[0]
    assert text.index("```bash") < text.index("\n## "), "the commands come before the first section"
    commands = [line.split("#")[0].strip() for line in first.strip().splitlines()]
    assert commands == ["pip install . && crlam demo --out demo-out", 'pip install ".[test]" && python -m pytest -q']
    ci = (ROOT / ".ci" / "run").read_text()
    assert 'python -m pip install ".[test]"' in ci and "python -m pytest -q" in ci
    assert len(text.splitlines()) <= 220


@pytest.mark.slow
def test_the_readme_python_snippet_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    text = README.read_text(encoding="utf-8")
    section = text[text.index("## Python API") :]
    (snippet,) = _blocks(section, "python")[:1]
    assert len(snippet.strip().splitlines()) <= 12
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(snippet, str(README), "exec"), {"__name__": "__readme__"})
    rmse = float(re.search(r"position RMSE ([0-9.]+) m", out.getvalue()).group(1))  # type: ignore[union-attr]
    assert rmse < 0.5, out.getvalue()


def test_readme_links_to_files_that_exist() -> None:
    text = README.read_text(encoding="utf-8")
    for target in re.findall(r"\]\(([^)#]+)\)", text):
        if not target.startswith("http"):
            assert (ROOT / target).exists(), target
