"""Public homes of the real datasets, a verified download into a cache, and the lookup.

The raw logs and relations come from the Freiburg SLAM-evaluation page (Kuemmerle et al. 2009),
the GMapping-corrected logs from the ``data/carmen`` folder of the ``acschaefer/ple`` GitHub
repository (Radish logs corrected with GMapping), pinned to a commit so the bytes cannot change
under the checksum. Every entry records the size and SHA-256 of the bytes its URL serves,
measured on the copies in the shared data folder: Freiburg serves the raw logs uncompressed
(``intel.clf``) while the shared copies are bzip2 files, so for those two the checksum is that
of the decompressed copy and ``local_sha256`` is that of the ``.bz2`` file itself.

Lookup order of :func:`find_dataset`: the data folder (``$CRLAM_DATA``, or ``../shared/data``
beside a source checkout, see :mod:`crlam.io.datasets`), then the cache (``--cache DIR``, else
``$XDG_CACHE_HOME/crlam``, else ``~/.cache/crlam``). Downloads are atomic: the bytes go to a
temporary file in the destination folder (pooch), are checked against the expected size and
SHA-256, and only then moved into place, so an interrupted or corrupted download never leaves a file
that the lookup would find.
"""

from __future__ import annotations

import http.client
import os
import urllib.error
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from crlam.errors import CrlamError
from crlam.io.datasets import DATASETS, DatasetNotFoundError, data_root
from crlam.limits import check_limit, limits

__all__ = [
    "REMOTE",
    "ChecksumError",
    "DatasetLocation",
    "DownloadError",
    "RemoteFile",
    "cache_dir",
    "download",
    "fetch",
    "find_dataset",
    "locate",
    "sha256_file",
]

FREIBURG_PAGE = "http://ais.informatik.uni-freiburg.de/slamevaluation/datasets.php"
_FREIBURG = "http://ais.informatik.uni-freiburg.de/slamevaluation/datasets/"
PLE_COMMIT = "8af88b28759f8a48b1bf33083a85f2013907c41d"
PLE_PAGE = "https://github.com/acschaefer/ple/tree/master/data/carmen"
_PLE = f"https://raw.githubusercontent.com/acschaefer/ple/{PLE_COMMIT}/data/carmen/"

DEFAULT_TIMEOUT = 60.0
_CHUNK = 1 << 16

Opener = Callable[[str, float], IO[bytes]]
"""``opener(url, timeout)`` returns a readable binary stream (default: ``urllib.request.urlopen``)."""


class DownloadError(CrlamError, OSError):
    """A download failed; the message names the URL."""


class ChecksumError(DownloadError):
    """Downloaded bytes do not have the expected size or SHA-256 (nothing was kept)."""


@dataclass(frozen=True)
class RemoteFile:
    """Where a dataset can be downloaded, and how to recognise the right bytes.

    Attributes
    ----------
    name : str
        Key, the same as in :data:`crlam.io.datasets.DATASETS`.
    url : str
        Download URL.
    cache_path : str
        Path inside the cache folder (the URL's file name under the dataset's folder).
    size : int
        Bytes served by ``url``.
    sha256 : str
        SHA-256 (hex) of those bytes.
    description : str
        What it is.
    homepage : str
        The page that documents it.
    local_sha256 : str or None
        SHA-256 of the shared data folder's copy when it differs from the download (the
        bzip2-compressed raw logs); None when the copy is byte-identical to the download.
    """

    name: str
    url: str
    cache_path: str
    size: int
    sha256: str
    description: str
    homepage: str
    local_sha256: str | None = None


def _table(*items: RemoteFile) -> dict[str, RemoteFile]:
    return {r.name: r for r in items}


# Sizes and checksums measured on /work/shared/data (the bzip2 logs decompressed with bzcat).
REMOTE: dict[str, RemoteFile] = _table(
    RemoteFile(
        "intel",
        _FREIBURG + "intel.clf",
        "intel/intel.clf",
        16_433_447,
        "8db0ad6231b48bad4118e6a2dc78e83213b2c306be3b4ed80a90969891abfe7b",
        "Intel Research Lab (Seattle) raw CARMEN log, uncompressed: 13,631 FLASER, 26,915 ODOM, 2,691 s",
        FREIBURG_PAGE,
        local_sha256="d9ce4addefc9405d5e78fd883d2214766552537d262009f8e6f0137885f9f72a",
    ),
    RemoteFile(
        "intel-relations",
        _FREIBURG + "intel.relations",
        "intel/intel.relations",
        265_713,
        "330378f153eeae652d6756c1746f335801f66c3e097d90611548e6c4f593c359",
        "Kuemmerle et al. 2009 reference relations for Intel, 2,984 lines",
        FREIBURG_PAGE,
    ),
    RemoteFile(
        "aces",
        _FREIBURG + "aces.clf",
        "aces/aces.clf",
        8_162_333,
        "1b6a069ebbfe261f2bae8bfe1ee91426932d2b964e8c2c0927b15663a4297390",
        "ACES building (Austin) raw CARMEN log, uncompressed: 7,374 FLASER, 7,375 ODOM, 1,366 s",
        FREIBURG_PAGE,
        local_sha256="b663e2976ed0621c2bec0cc20c4e7cc117b88db5bac6f921d3fbaa9685d2232a",
    ),
    RemoteFile(
        "aces-relations",
        _FREIBURG + "aces.relations",
        "aces/aces.relations",
        99_426,
        "11a15800a751b6f9413078a021d49c7cda85a768c2a465433b4fae7ef57b03d5",
        "Kuemmerle et al. 2009 reference relations for ACES, 1,279 lines",
        FREIBURG_PAGE,
    ),
    RemoteFile(
        "intel-corrected",
        _PLE + "intel-corrected.log.gz",
        "corrected/intel-corrected.log.gz",
        448_366,
        "71bef16e9926506cf7417995ef35ace09dbd5de067fd042a3aab85188b5480dc",
        "GMapping-corrected Intel log: 910 processed scans, stamps are the raw logger times",
        PLE_PAGE,
    ),
    RemoteFile(
        "aces-corrected",
        _PLE + "aces-corrected.log.gz",
        "corrected/aces-corrected.log.gz",
        202_430,
        "5434d44384166250608a64d3a8c32de84512f82c46cb60a2657f138592024569",
        "GMapping-corrected ACES log: 440 processed scans, stamps are the raw logger times",
        PLE_PAGE,
    ),
    RemoteFile(
        "freiburg-101-corrected",
        _PLE + "freiburg-101-corrected.log.gz",
        "corrected/freiburg-101-corrected.log.gz",
        223_460,
        "7792de88bcb050f8edba92914aea75e8ec2fb73b483c01903bd2753aa655e982",
        "GMapping-corrected Freiburg building 101 log, 360 beams",
        PLE_PAGE,
    ),
    RemoteFile(
        "edmonton-corrected",
        _PLE + "edmonton-corrected.log.gz",
        "corrected/edmonton-corrected.log.gz",
        194_337,
        "96599a91e0cc9cb2570dbb92f92bbdf1e3a405b16aa99f6d3ce1a703011befdb",
        "GMapping-corrected Edmonton convention centre log",
        PLE_PAGE,
    ),
)


def cache_dir(override: str | os.PathLike[str] | None = None) -> Path:
    """The download cache: ``override``, else ``$XDG_CACHE_HOME/crlam``, else ``~/.cache/crlam``."""
    if override is not None:
        return Path(override).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg).expanduser() if xdg else Path.home() / ".cache") / "crlam"


def _known(name: str) -> None:
    if name not in DATASETS and name not in REMOTE:
        known = ", ".join(sorted(set(DATASETS) | set(REMOTE)))
        raise DatasetNotFoundError(f"unknown dataset {name!r}; known: {known}")


@dataclass(frozen=True)
class DatasetLocation:
    """Where a dataset was found.

    Attributes
    ----------
    name : str
    path : Path or None
        The file, or None when there is no local copy.
    source : str
        ``"data folder"`` (``$CRLAM_DATA`` or ``../shared/data``), ``"cache"`` or ``"missing"``.
    """

    name: str
    path: Path | None
    source: str


def locate(name: str, *, cache: str | os.PathLike[str] | None = None) -> DatasetLocation:
    """Look a dataset up in the data folder, then in the cache; never raises for a known name."""
    _known(name)
    root = data_root()
    if root is not None and name in DATASETS and (root / DATASETS[name].relative_path).is_file():
        return DatasetLocation(name, root / DATASETS[name].relative_path, "data folder")
    folder = cache_dir(cache)
    rels = [REMOTE[name].cache_path] if name in REMOTE else []
    rels += [DATASETS[name].relative_path] if name in DATASETS else []
    for rel in rels:
        if (folder / rel).is_file():
            return DatasetLocation(name, folder / rel, "cache")
    return DatasetLocation(name, None, "missing")


def find_dataset(name: str, *, cache: str | os.PathLike[str] | None = None) -> Path:
    """Path of a dataset by name: the data folder first, then the cache.

    Raises
    ------
    DatasetNotFoundError
        For an unknown name, or when neither place holds the file; the message says where it
        looked and how to download it.
    """
    loc = locate(name, cache=cache)
    if loc.path is not None:
        return loc.path
    root = data_root()
    where = f"data folder {root}" if root is not None else "no data folder ($CRLAM_DATA unset, empty or missing)"
    hint = f"; download it with `crlam data fetch {name}`" if name in REMOTE else " (it has no public download)"
    raise DatasetNotFoundError(f"dataset {name!r} not found ({where}; cache {cache_dir(cache)}){hint}")


def sha256_file(path: str | os.PathLike[str]) -> str:
    """SHA-256 (hex) of a file."""
    import pooch

    return str(pooch.file_hash(str(path), alg="sha256"))


def _urlopen(url: str, timeout: float) -> IO[bytes]:
    return urllib.request.urlopen(url, timeout=timeout)  # type: ignore[no-any-return]


def _content_length(response: Any) -> int | None:
    headers = getattr(response, "headers", None)
    value = headers.get("Content-Length") if headers is not None else None
    try:
        return int(value) if value is not None else None
    except ValueError:
        return None


@dataclass(frozen=True)
class _StreamDownloader:
    """A pooch downloader that reads ``url`` through ``opener`` (``file://`` copies, mirrors, tests).

    Pooch calls it with a temporary file in the destination folder, then checks the SHA-256 and
    moves the file into place; this class adds the size check and the progress bar.
    """

    opener: Opener
    timeout: float
    size: int | None
    progress: bool
    label: str

    def __call__(self, url: str, output_file: str, pooch_instance: object, check_only: bool = False) -> None:
        from tqdm import tqdm

        n = 0
        # Never more than the expected size (or, with none, the download_bytes limit) is written:
        # a server (or a file:// URL such as /dev/zero) sending more is stopped at once.
        cap = self.size if self.size is not None else limits().download_bytes
        try:
            with self.opener(url, self.timeout) as response, open(output_file, "wb") as out:
                announced = _content_length(response)
                if announced is not None and announced > cap:
                    _too_large(url, announced, self.size)
                total = announced or self.size
                with tqdm(
                    total=total, unit="B", unit_scale=True, unit_divisor=1024, desc=self.label, disable=not self.progress
                ) as bar:
                    for block in iter(lambda: response.read(_CHUNK), b""):
                        if n + len(block) > cap:
                            _too_large(url, n + len(block), self.size)
                        out.write(block)
                        n += len(block)
                        bar.update(len(block))
        except CrlamError:
            raise
        except (urllib.error.URLError, http.client.HTTPException, OSError, ValueError) as exc:
            reason = getattr(exc, "reason", None) or exc
            raise DownloadError(f"download of {url} failed: {reason}") from exc
        if self.size is not None and n != self.size:
            raise ChecksumError(f"download of {url} has {n} bytes, expected {self.size}; discarded")


def _too_large(url: str, n: int, size: int | None) -> None:
    if size is not None:
        raise ChecksumError(f"download of {url} sends {n:,} bytes or more, expected {size:,}; discarded")
    check_limit("download_bytes", n, f"download of {url}")


def download(
    url: str,
    dest: str | os.PathLike[str],
    *,
    sha256: str,
    size: int | None = None,
    opener: Opener | None = None,
    progress: bool = True,
    timeout: float = DEFAULT_TIMEOUT,
    label: str | None = None,
) -> Path:
    """Download ``url`` to ``dest`` with pooch, verifying its SHA-256 (and size), atomically.

    Pooch downloads into a temporary file beside ``dest``, checks the SHA-256 and only then moves
    the file into place, so an interrupted or corrupted download never leaves a file that the
    lookup would find, and a good file already at ``dest`` is never replaced by a bad one.

    Parameters
    ----------
    url : str
        ``http(s)://`` or ``file://`` URL (read by ``urllib.request.urlopen``).
    dest : str or PathLike
        Final path; its folder is created. Replaced only by verified bytes, and downloaded
        again only when it does not verify.
    sha256 : str
        Expected SHA-256 (hex).
    size : int, optional
        Expected size (bytes): a source sending more is stopped at once, one sending less is
        refused; the progress bar's total when the server sends none.
    opener : callable, optional
        ``opener(url, timeout)`` -> binary stream; given, it reads the URL instead of
        ``urllib.request.urlopen`` (mirrors, tests).
    progress : bool
        Show a tqdm progress bar (on stderr).
    timeout : float
        Socket timeout (s).
    label : str, optional
        Progress bar label (default: the file name).

    Raises
    ------
    DownloadError
        When the URL cannot be read; the message names it.
    ChecksumError
        When the bytes have the wrong size or SHA-256; nothing is written at ``dest``. A source
        sending more than ``size`` bytes is stopped as soon as it does.
    ResourceLimitError
        When no ``size`` is given and the source sends more than the ``download_bytes`` limit.
    """
    import pooch

    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    pooch.get_logger().setLevel("WARNING")
    # Pooch checks the hash and moves the file into place; the bytes come through our streaming
    # downloader on every scheme, so the size cap holds for http(s) too.
    downloader = _StreamDownloader(opener or _urlopen, timeout, size, progress, label or dest.name)
    try:
        fetched = pooch.retrieve(
            url, known_hash=f"sha256:{sha256.lower()}", fname=dest.name, path=dest.parent, downloader=downloader
        )
    except CrlamError:
        raise
    except ValueError as exc:  # pooch: the SHA-256 does not match
        raise ChecksumError(f"download of {url} does not have SHA-256 {sha256} ({exc}); discarded") from exc
    return Path(fetched)


def fetch(
    name: str,
    *,
    cache: str | os.PathLike[str] | None = None,
    url: str | None = None,
    opener: Opener | None = None,
    progress: bool = True,
    force: bool = False,
    timeout: float = DEFAULT_TIMEOUT,
) -> Path:
    """Download a dataset into the cache (verified), unless a verified copy is already there.

    Parameters
    ----------
    name : str
        A key of :data:`REMOTE`.
    cache : str or PathLike, optional
        Cache folder (default: :func:`cache_dir`).
    url : str, optional
        Download from this URL instead (a mirror, a ``file://`` copy); the bytes must still
        have the registered size and SHA-256.
    opener, progress, timeout
        See :func:`download`.
    force : bool
        Download again even if the cached copy verifies.

    Returns
    -------
    Path
        The cached file.
    """
    _known(name)
    if name not in REMOTE:
        raise DatasetNotFoundError(f"dataset {name!r} has no public download (it is derived from another file)")
    remote = REMOTE[name]
    dest = cache_dir(cache) / remote.cache_path
    if not force and dest.is_file() and dest.stat().st_size == remote.size and sha256_file(dest) == remote.sha256:
        return dest
    # Forced: download beside the cached copy and replace it only once the new bytes verify.
    target = dest.with_name(f".{dest.name}.forced") if force else dest
    if force:
        target.unlink(missing_ok=True)
    got = download(
        url or remote.url,
        target,
        sha256=remote.sha256,
        size=remote.size,
        opener=opener,
        progress=progress,
        timeout=timeout,
        label=name,
    )
    if force:
        os.replace(got, dest)
    return dest
