"""The SLAM settings that take one of a few names (``match_climb``, ``degeneracy``): their values
and presets, and the checks of config files, command-line flags and sweep flags."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import NamedTuple

import pytest

from crlam.cli import main
from crlam.errors import ConfigError
from crlam.slam import DEGENERACIES, MATCH_CLIMBS, SlamConfig, presets

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


class Choice(NamedTuple):
    field: str
    values: tuple[str, ...]
    paper: str
    robust: str
    flag: str


CHOICES = [
    Choice("match_climb", MATCH_CLIMBS, paper="score", robust="score", flag="--match-climb"),
    Choice("degeneracy", DEGENERACIES, paper="off", robust="remap", flag="--degeneracy"),
]
IDS = [c.field for c in CHOICES]


def test_the_names() -> None:
    assert MATCH_CLIMBS == ("score", "posterior")
    assert DEGENERACIES == ("off", "remap")


@pytest.mark.parametrize("choice", CHOICES, ids=IDS)
def test_values_and_presets(choice: Choice) -> None:
    # A bare SlamConfig is the paper's.
    assert getattr(SlamConfig(), choice.field) == choice.paper
    assert getattr(SlamConfig.from_preset("paper"), choice.field) == choice.paper
    assert getattr(SlamConfig.from_preset("robust"), choice.field) == choice.robust
    for value in choice.values:
        assert getattr(SlamConfig(**{choice.field: value}), choice.field) == value
    for bad in (choice.values[-1].capitalize(), "", None, 1):
        with pytest.raises(ConfigError, match=choice.field):
            SlamConfig(**{choice.field: bad})


@pytest.mark.parametrize("choice", CHOICES, ids=IDS)
def test_a_config_file_is_checked(choice: Choice, tmp_path: Path) -> None:
    path = tmp_path / "config.toml"
    path.write_text(f'[slam]\n{choice.field} = "sideways"\n')
    with pytest.raises(ConfigError, match=choice.field):
        presets.load_config_file(path)


@pytest.mark.parametrize("choice", CHOICES, ids=IDS)
def test_the_flag_is_checked(choice: Choice, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["slam", "intel", "--out", str(tmp_path / "x"), choice.flag, "sideways"])
    assert choice.flag in capsys.readouterr().err


@pytest.mark.parametrize("choice", CHOICES, ids=IDS)
def test_the_sweeps_take_the_flag(choice: Choice, tmp_path: Path) -> None:
    # The value the robust preset does not take, so that the flag is what sets it.
    value = next(v for v in choice.values if v != choice.robust)
    argv = ["experiment", "table1", "--out", str(tmp_path), "--runs", "1", "--scans", "20", "--particles", "2"]
    argv += ["--methods", "clam", "--preset", "robust", choice.flag, value, "--workers", "1", "--quiet"]
    assert main(argv) == 0
    config = tomllib.loads((tmp_path / "runs" / "clam_run00" / "config.toml").read_text())
    assert config["slam"][choice.field] == value
