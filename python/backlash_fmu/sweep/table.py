"""The sweep's table on disk, written as the rows arrive, and what lets an interrupted sweep resume.

- `Writer`: DIR/samples.csv grows row by row in the order the rows arrive (the header once, one
  row a line, flushed after every batch), so a sweep killed at any moment keeps every row it
  received; beside it DIR/manifest.json names what wrote the rows (seed, model, a digest of the
  config and of the archive), written before the first row.
- `finish`: at the end, the table is put in sample order in place (a streaming merge of its runs
  of consecutive samples: the client never holds the rows; the file is rewritten only when it is
  not in order yet), so that the same seed gives the same table byte for byte, whatever the
  cluster, the order of completion or the interruptions.
- `resume_state`: the rows already in DIR/samples.csv (a torn last line, from a kill mid-write,
  is cut off) as intervals of sample indices, after checking that DIR/manifest.json names the
  same seed, model, config and archive; `pending` yields the samples still to run.
- `Rows`: the finished table read back lazily (a sequence of row dicts, parsed on each pass,
  that the summary and the plots iterate without the client holding every row).

A cell is the shortest text that reads back as the same value (`repr` of a float or an int,
`true`/`false`), so a table read back gives the very rows that were written. This module needs
only the standard library (the pre-flight check, check.py, runs `check_manifest`).
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Iterator

TABLE = "samples.csv"
MANIFEST = "manifest.json"
# What a manifest's "format" says; a manifest of another format is not resumed.
FORMAT = "backlash_fmu.sweep table 1"
# Bytes copied at a time when the table is put in order.
BLOCK = 1 << 20


class TableError(ValueError):
    """A table or manifest that cannot be resumed; the message is one line."""


def cell(value: object) -> str:
    # repr: the shortest text that reads back as the same float, so tables compare byte for byte.
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value)


def line(row: dict, columns: tuple[str, ...]) -> str:
    """One row of the table, newline included (the same bytes as csv.writer would write: no cell
    holds a comma, a quote or a newline)."""
    return ",".join(cell(row[c]) for c in columns) + "\n"


def write_table(path: Path, rows: Iterable[dict], columns: tuple[str, ...] | None = None) -> None:
    """A whole table at once, in sample order (rows held by the caller: tests, small sweeps)."""
    rows = sorted(rows, key=lambda r: r["sample"])
    if columns is None:
        columns = tuple(rows[0]) if rows else ("sample",)
    with open(path, "w", newline="") as f:
        f.write(",".join(columns) + "\n")
        for row in rows:
            f.write(line(row, columns))


# ------------------------------------------------------------------------------------------
# The manifest: what wrote the rows
# ------------------------------------------------------------------------------------------


def digest(value: Any) -> str:
    """SHA-256 of a JSON-able value (keys sorted; anything else by its str)."""
    return hashlib.sha256(json.dumps(value, sort_keys=True, default=str).encode()).hexdigest()


def manifest(*, seed: int, model: str, config: dict[str, Any], config_file: dict, archive: bytes) -> dict[str, Any]:
    """What a table's rows depend on besides their index: the seed, the model, the config as run
    (distributions and settings, numbers as exact text), the config file's entries (what the
    pre-flight check can compare without the defaults), and the archive's bytes."""
    return {
        "format": FORMAT,
        "seed": seed,
        "model": model,
        "config": digest(config),
        "config_file": digest(config_file),
        "archive": hashlib.sha256(archive).hexdigest(),
    }


def read_manifest(out: Path) -> dict[str, Any] | None:
    path = out / MANIFEST
    try:
        text = path.read_text()
    except FileNotFoundError:
        return None
    except OSError as e:
        raise TableError(f"--resume: cannot read {path}: {e.strerror}") from None
    try:
        found = json.loads(text)
    except json.JSONDecodeError:
        found = None
    if not isinstance(found, dict) or found.get("format") != FORMAT:
        raise TableError(f"--resume: {path} is not a manifest of this sweep")
    return found


# Differences named in the order they are looked for, with how the refusal says them.
_MANIFEST_KEYS = (
    ("model", "model"),
    ("seed", "seed"),
    ("config_file", "config file"),
    ("config", "config (distributions, settings or --accuracy)"),
    ("archive", "FMU archive"),
)


def check_manifest(out: Path, expected: dict[str, Any]) -> dict[str, Any] | None:
    """Refuses to resume the table in `out` when its manifest names another seed, model, config
    or archive than `expected` (only the keys given are compared: the pre-flight check gives
    seed, model and config_file). Returns the manifest, or None when `out` holds no table."""
    table = out / TABLE
    found = read_manifest(out)
    if not table.exists():
        return found
    if found is None:
        raise TableError(f"--resume: {table} has no {MANIFEST} beside it: which seed and config wrote it is unknown "
                         "(run without --resume to start afresh)")
    for key, name in _MANIFEST_KEYS:
        if key in expected and found.get(key) != expected[key]:
            if key in ("seed", "model"):
                says = f"{name} {found.get(key)!r}, not {expected[key]!r}"
            else:
                says = f"another {name}"
            raise TableError(f"--resume: {table} holds samples of {says} (run without --resume to start afresh, "
                             "or give another --out)")
    return found


# ------------------------------------------------------------------------------------------
# Reading a table back: runs of consecutive samples
# ------------------------------------------------------------------------------------------


@dataclass
class Run:
    """Consecutive lines of the table holding samples first, first + 1, ..., last."""

    first: int
    last: int
    offset: int
    size: int


@dataclass
class Scan:
    columns: tuple[str, ...]
    runs: list[Run]
    # Where the complete lines end (a torn last line starts there).
    end: int
    torn: bool
    rows: int = 0
    header_size: int = 0
    done: list[tuple[int, int]] = field(default_factory=list)

    @property
    def in_order(self) -> bool:
        """Every sample once, in order: the table as finished."""
        return len(self.runs) <= 1 and (not self.runs or self.runs[0].first == 0)


def scan(path: Path) -> Scan:
    """The table at `path` read line by line, keeping only its runs of consecutive samples (a
    few per task, never the rows). A last line without its newline (a write cut short by a kill)
    is left out and reported as torn; any other line that is not a row is an error."""
    runs: list[Run] = []
    rows = 0
    with open(path, "rb") as f:
        header = f.readline()
        if not header.endswith(b"\n"):
            raise TableError(f"--resume: {path} has no complete header line")
        columns = tuple(header[:-1].decode().split(","))
        if columns[0] != "sample":
            raise TableError(f"--resume: {path} is not a sweep's table (its first column is {columns[0]!r})")
        offset = end = len(header)
        torn = False
        number = 1
        for text in f:
            number += 1
            if not text.endswith(b"\n"):
                torn = True
                break
            head, _, _ = text.partition(b",")
            try:
                index = int(head)
            except ValueError:
                index = -1
            if index < 0 or text.count(b",") != len(columns) - 1:
                raise TableError(f"--resume: line {number} of {path} is not a row of the table")
            last = runs[-1] if runs else None
            if last is not None and index == last.last + 1 and last.offset + last.size == offset:
                last.last = index
                last.size += len(text)
            else:
                runs.append(Run(index, index, offset, len(text)))
            offset += len(text)
            end = offset
            rows += 1
    done = _intervals(runs)
    return Scan(columns, runs, end, torn, rows, len(header), done)


def _intervals(runs: list[Run]) -> list[tuple[int, int]]:
    """The samples of `runs` as sorted, disjoint half-open intervals [start, stop)."""
    out: list[tuple[int, int]] = []
    for r in sorted(runs, key=lambda r: r.first):
        start, stop = r.first, r.last + 1
        if out and start <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], stop))
        else:
            out.append((start, stop))
    return out


def count(done: list[tuple[int, int]]) -> int:
    return sum(stop - start for start, stop in done)


def pending(samples: int, done: list[tuple[int, int]]) -> Iterator[int]:
    """The indices below `samples` outside the intervals `done`, in order."""
    i = 0
    for start, stop in done:
        yield from range(i, min(start, samples))
        i = max(i, stop)
    yield from range(i, samples)


# ------------------------------------------------------------------------------------------
# Resuming and writing
# ------------------------------------------------------------------------------------------


@dataclass
class ResumeState:
    columns: tuple[str, ...]
    done: list[tuple[int, int]]
    # The length of the table's complete lines (a torn last line is cut off there).
    end: int
    torn: bool

    @property
    def rows(self) -> int:
        return count(self.done)


def resume_state(out: Path, expected: dict[str, Any], samples: int) -> ResumeState | None:
    """What a sweep resumed in `out` finds there: None when there is no table yet (the sweep
    starts afresh), else its rows as intervals of samples. Raises TableError (one line) when the
    manifest names another seed, model, config or archive, or a row's sample is not below
    `samples`."""
    check_manifest(out, expected)
    path = out / TABLE
    if not path.exists():
        return None
    found = scan(path)
    if found.done and found.done[-1][1] > samples:
        raise TableError(f"--resume: {path} holds sample {found.done[-1][1] - 1}, beyond --samples {samples}")
    return ResumeState(found.columns, found.done, found.end, found.torn)


class Writer:
    """Appends rows to DIR/samples.csv as they arrive (the header once, one row a line, flushed
    after each batch). Nothing is created before the first batch: a sweep refused or failed
    before any row leaves the directory as it was. A fresh table replaces any table and manifest
    there (the manifest removed first, written again after the header, so that a table is never
    beside a manifest that did not write it); a resumed one is appended to, after cutting off a
    torn last line."""

    def __init__(self, out: Path, manifest: dict[str, Any], resume: ResumeState | None = None,
                 columns: tuple[str, ...] | None = None) -> None:
        """`columns`: the table's (default: the keys of the first row, in their order)."""
        self.out = Path(out)
        self.path = self.out / TABLE
        self.manifest = manifest
        self.resume = resume
        self.columns = tuple(columns) if columns is not None else None
        if resume is not None:
            if self.columns is not None and resume.columns != self.columns:
                raise TableError(f"--resume: {self.path} has the columns {','.join(resume.columns)}, "
                                 f"not {','.join(self.columns)}")
            self.columns = resume.columns
        self.file: Any = None
        self.written = 0

    def _open(self, first: dict) -> None:
        self.out.mkdir(parents=True, exist_ok=True)
        if self.resume is not None:
            self.file = open(self.path, "r+b")
            self.file.truncate(self.resume.end)
            self.file.seek(self.resume.end)
            return
        (self.out / MANIFEST).unlink(missing_ok=True)
        if self.columns is None:
            self.columns = tuple(first)
        self.file = open(self.path, "wb")
        self.file.write((",".join(self.columns) + "\n").encode())
        self.file.flush()
        write_manifest(self.out, self.manifest)

    def write(self, rows: list[dict]) -> None:
        if not rows:
            return
        if self.file is None:
            self._open(rows[0])
        self.file.write("".join(line(row, self.columns) for row in rows).encode())
        self.file.flush()
        self.written += len(rows)

    def close(self) -> None:
        if self.file is not None:
            self.file.close()
            self.file = None


def write_manifest(out: Path, value: dict[str, Any]) -> None:
    tmp = out / (MANIFEST + ".tmp")
    tmp.write_text(json.dumps(value, indent=2) + "\n")
    os.replace(tmp, out / MANIFEST)


def finish(out: Path, samples: int) -> int:
    """Puts DIR/samples.csv in sample order, in place: its runs of consecutive samples sorted by
    their first sample and copied block by block into a new file that replaces it (nothing is
    rewritten when it is in order already). A sample written twice (a task's rows received again)
    is kept once. Raises TableError when a sample below `samples` is missing. Returns the number
    of rows."""
    path = Path(out) / TABLE
    found = scan(path)
    if found.torn:
        with open(path, "r+b") as f:
            f.truncate(found.end)
    if found.done != [(0, samples)]:
        missing = next(pending(samples, found.done), None)
        raise TableError(f"{path}: sample {missing} is missing" if missing is not None
                         else f"{path}: samples beyond {samples - 1}")
    if found.in_order:
        return samples
    tmp = path.with_name(TABLE + ".sorting")
    with open(path, "rb") as src, open(tmp, "wb") as dst:
        dst.write(src.read(found.header_size))
        following = 0  # the next sample to copy
        for run in sorted(found.runs, key=lambda r: (r.first, -r.last)):
            if run.last < following:
                continue
            src.seek(run.offset)
            left = run.size
            if run.first < following:
                # The run's first samples were copied already: skip their lines.
                for _ in range(following - run.first):
                    left -= len(src.readline())
            while left > 0:
                block = src.read(min(BLOCK, left))
                dst.write(block)
                left -= len(block)
            following = run.last + 1
    os.replace(tmp, path)
    return samples


# ------------------------------------------------------------------------------------------
# The finished table, read back lazily
# ------------------------------------------------------------------------------------------


def _bool(text: str) -> bool:
    if text not in ("true", "false"):
        raise ValueError(f"expected true or false, got {text!r}")
    return text == "true"


def _reader(text: str) -> Any:
    """How a column reads back, from one of its cells: true/false a bool, digits an int (a
    float's repr always has a point, an exponent, inf or nan), anything else a float."""
    if text in ("true", "false"):
        return _bool
    if text.lstrip("-").isdigit():
        return int
    return float


class Rows:
    """The rows of a finished table as a sequence of dicts, read from the file on every pass
    (`len`, iteration, and indexing, which reads up to the row): what the summary and the plots
    are given, so that the client never holds them all. Each row reads back as written: the
    sample an int, `meets` a bool, every other cell a float (repr's text reads back as the same
    float)."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        with open(self.path) as f:
            self.columns = tuple(f.readline().rstrip("\n").split(","))
            self._len = sum(1 for _ in f)

    def __len__(self) -> int:
        return self._len

    def __iter__(self) -> Iterator[dict]:
        columns = self.columns
        readers = None
        with open(self.path) as f:
            f.readline()
            for text in f:
                cells = text.rstrip("\n").split(",")
                if readers is None:
                    readers = [_reader(v) for v in cells]
                yield {c: read(v) for c, read, v in zip(columns, readers, cells)}

    def __getitem__(self, i: int) -> dict:
        if i < 0:
            i += self._len
        if not 0 <= i < self._len:
            raise IndexError(i)
        for k, row in enumerate(self):
            if k == i:
                return row
        raise IndexError(i)

    def __bool__(self) -> bool:
        return self._len > 0
