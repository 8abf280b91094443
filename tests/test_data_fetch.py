"""Dataset registry, verified atomic downloads and the ``crlam data`` command; never on the network."""

from __future__ import annotations

import argparse
import bz2
import hashlib
import io
from pathlib import Path
from typing import IO

import pytest

import crlam.io.fetch as fetch_mod
from crlam.errors import CrlamError
from crlam.io.datasets import DATASETS, DatasetNotFoundError
from crlam.io.fetch import (
    REMOTE,
    ChecksumError,
    DownloadError,
    cache_dir,
    download,
    fetch,
    find_dataset,
    locate,
    sha256_file,
)

_real_urlopen = fetch_mod._urlopen


@pytest.fixture(autouse=True)
def offline(monkeypatch: pytest.MonkeyPatch) -> None:
    """Only file:// URLs may be opened: a test that would reach the network fails instead."""

    def guarded(url: str, timeout: float) -> IO[bytes]:
        assert url.startswith("file://"), f"test tried to open {url}"
        return _real_urlopen(url, timeout)

    monkeypatch.setattr(fetch_mod, "_urlopen", guarded)


@pytest.fixture
def no_data_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty data folder, so that lookups fall through to the cache."""
    empty = tmp_path / "empty-data"
    empty.mkdir()
    monkeypatch.setenv("CRLAM_DATA", str(empty))
    return tmp_path / "cache"


def payload(tmp_path: Path, data: bytes = b"FLASER 3 1 2 3 0 0 0 0 0 0 1.0 h 1.0\n" * 100) -> tuple[Path, str]:
    src = tmp_path / "src.clf"
    src.write_bytes(data)
    return src, hashlib.sha256(data).hexdigest()


def leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


def test_download_from_a_file_url_is_verified_and_atomic(tmp_path: Path) -> None:
    src, sha = payload(tmp_path)
    dest = tmp_path / "out" / "sub" / "log.clf"
    assert download(src.as_uri(), dest, sha256=sha, size=src.stat().st_size, progress=False) == dest
    assert dest.read_bytes() == src.read_bytes()
    assert leftovers(dest.parent) == ["log.clf"]  # no temporary file left


@pytest.mark.parametrize("what", ("sha256", "size"))
def test_a_corrupted_download_is_rejected_and_nothing_is_kept(tmp_path: Path, what: str) -> None:
    src, sha = payload(tmp_path)
    dest = tmp_path / "out" / "log.clf"
    bad = {"sha256": {"sha256": "0" * 64}, "size": {"sha256": sha, "size": 5}}[what]
    with pytest.raises(ChecksumError, match="src.clf"):
        download(src.as_uri(), dest, progress=False, **bad)  # type: ignore[arg-type]
    assert leftovers(dest.parent) == []


def test_an_existing_file_is_not_replaced_by_a_bad_download(tmp_path: Path) -> None:
    src, _ = payload(tmp_path)
    dest = tmp_path / "log.clf"
    dest.write_bytes(b"previous")
    with pytest.raises(ChecksumError):
        download(src.as_uri(), dest, sha256="f" * 64, progress=False)
    assert dest.read_bytes() == b"previous"


def test_an_unreachable_url_is_a_clean_error_naming_it(tmp_path: Path) -> None:
    url = (tmp_path / "nope.clf").as_uri()
    with pytest.raises(DownloadError, match="nope.clf") as e:
        download(url, tmp_path / "out" / "x", sha256="0" * 64, progress=False)
    assert url in str(e.value) and isinstance(e.value, CrlamError)
    assert leftovers(tmp_path / "out") == []


def test_an_http_url_to_a_refused_connection_is_a_clean_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # Port 9 (discard) on the loopback address: nothing listens, the connection is refused at once.
    monkeypatch.setattr(fetch_mod, "_urlopen", _real_urlopen)  # the loopback address only
    url = "http://127.0.0.1:9/intel.clf"
    with pytest.raises(DownloadError, match="127.0.0.1:9/intel.clf"):
        download(url, tmp_path / "out" / "intel.clf", sha256="0" * 64, progress=False, timeout=5.0)
    assert leftovers(tmp_path / "out") == []


def test_cache_dir_follows_override_then_xdg_then_home(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    assert cache_dir(tmp_path / "c") == tmp_path / "c"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "crlam"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert cache_dir() == Path.home() / ".cache" / "crlam"


def test_registry_is_consistent() -> None:
    for name, r in REMOTE.items():
        assert name in DATASETS and r.name == name
        assert r.url.rsplit("/", 1)[1] == Path(r.cache_path).name
        assert len(r.sha256) == 64 and r.size > 0 and r.description and r.homepage.startswith("http")


@pytest.mark.realdata
@pytest.mark.parametrize("name", sorted(REMOTE))
def test_registry_checksums_match_the_shared_copies(data_dir: Path, name: str) -> None:
    r = REMOTE[name]
    local = data_dir / DATASETS[name].relative_path
    if r.local_sha256 is None:  # byte-identical to the download
        assert local.stat().st_size == r.size and sha256_file(local) == r.sha256
    else:  # Freiburg serves the log uncompressed; the shared copy is its bzip2
        assert sha256_file(local) == r.local_sha256
        with bz2.open(local, "rb") as fh:
            data = fh.read()
        assert len(data) == r.size and hashlib.sha256(data).hexdigest() == r.sha256


@pytest.mark.realdata
def test_fetch_from_a_file_url_then_find_it_in_the_cache(data_dir: Path, no_data_folder: Path) -> None:
    cache = no_data_folder
    with pytest.raises(DatasetNotFoundError, match="crlam data fetch aces-relations"):
        find_dataset("aces-relations", cache=cache)
    src = data_dir / "aces" / "aces.relations"
    path = fetch("aces-relations", cache=cache, url=src.as_uri(), progress=False)
    assert path == cache / "aces" / "aces.relations" and path.read_bytes() == src.read_bytes()
    assert find_dataset("aces-relations", cache=cache) == path and locate("aces-relations", cache=cache).source == "cache"

    def must_not_download(url: str, timeout: float) -> IO[bytes]:
        raise AssertionError("a verified cached copy must not be downloaded again")

    assert fetch("aces-relations", cache=cache, opener=must_not_download, progress=False) == path


class _Served(io.BytesIO):
    """What a monkeypatched opener returns: the bytes of a local copy, like an HTTP response."""


@pytest.mark.realdata
def test_fetch_raw_log_through_a_patched_opener(data_dir: Path, no_data_folder: Path) -> None:
    cache = no_data_folder
    with bz2.open(data_dir / "aces" / "aces.clf.bz2", "rb") as fh:
        content = fh.read()
    seen: list[str] = []

    def opener(url: str, timeout: float) -> IO[bytes]:
        seen.append(url)
        return _Served(content)

    path = fetch("aces", cache=cache, opener=opener, progress=False)
    assert seen == [REMOTE["aces"].url] and path == cache / "aces" / "aces.clf"
    assert find_dataset("aces", cache=cache) == path

    def corrupt(url: str, timeout: float) -> IO[bytes]:
        return _Served(content[:-10] + b"0123456789")

    with pytest.raises(ChecksumError, match="aces.clf"):
        fetch("aces", cache=cache, opener=corrupt, progress=False, force=True)
    assert sha256_file(path) == REMOTE["aces"].sha256  # the good copy is untouched


def test_unknown_and_undownloadable_names(no_data_folder: Path) -> None:
    with pytest.raises(DatasetNotFoundError, match="unknown dataset"):
        find_dataset("nope", cache=no_data_folder)
    with pytest.raises(DatasetNotFoundError, match="no public download"):
        fetch("cave-map", cache=no_data_folder, progress=False)


def data_parser() -> argparse.ArgumentParser:
    from crlam.cli.data import add_parser as add_data_parser

    parser = argparse.ArgumentParser(prog="crlam")
    add_data_parser(parser.add_subparsers(dest="command"))
    return parser


def test_cli_data_list_shows_every_dataset_and_where(no_data_folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (no_data_folder / "intel").mkdir(parents=True)
    (no_data_folder / "intel" / "intel.relations").write_bytes(b"cached")
    args = data_parser().parse_args(["data", "list", "--cache", str(no_data_folder)])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    for name in DATASETS:
        assert name in out
    line = next(ln for ln in out.splitlines() if ln.startswith("intel-relations "))
    assert "cache" in line and str(no_data_folder / "intel" / "intel.relations") in line
    assert next(ln for ln in out.splitlines() if ln.startswith("aces ")).split()[3] == "missing"
    assert REMOTE["aces"].url in out


@pytest.mark.realdata
def test_cli_data_fetch_with_a_file_url(data_dir: Path, no_data_folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = data_dir / "corrected" / "aces-corrected.log.gz"
    argv = ["data", "fetch", "aces-corrected", "--cache", str(no_data_folder), "--url", src.as_uri(), "--quiet"]
    args = data_parser().parse_args(argv)
    assert args.func(args) == 0
    assert "SHA-256 verified" in capsys.readouterr().out
    assert (no_data_folder / "corrected" / "aces-corrected.log.gz").read_bytes() == src.read_bytes()
    # The wrong file at the URL is rejected with an error naming it.
    bad = data_dir / "corrected" / "intel-corrected.log.gz"
    args = data_parser().parse_args([*argv[:-2], bad.as_uri(), "--force", "--quiet"])
    with pytest.raises(CrlamError, match="intel-corrected.log.gz"):
        args.func(args)
