"""The CSV exchange format of measured runs (docs/csv-format.md), read and written.

A file is UTF-8, comma-separated: optional ``# key: value`` comment lines (kept as metadata, unknown
keys included), one header row naming the columns, then one row of numbers per sample. The required
columns are :data:`rigctl.data.REQUIRED_COLUMNS` in SI units; any other column is carried along in
``MeasuredRun.extra`` and written back after the required ones.

Reading parses the numeric rows in bulk with :func:`numpy.loadtxt` straight from the file (a 205k-row
run loads in about a quarter of a second, and memory holds the numbers, not the text: a record of
hours fits where its text would not); only when that fails, or a required value is not finite, does
a slow pass over the text name the exact line and column of the problem. Every problem raises
:class:`rigctl.data.DataError` naming file, line
(1-based, as an editor counts them) and column.

Writing formats every value with ``repr`` (the shortest text that parses back to the same
float64), so write -> read is exact, and goes through a temporary file renamed over the target:
a failed export never leaves a half-written file.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from rigctl.data import REQUIRED_COLUMNS, DataError, FloatArray, MeasuredRun
from rigctl.io.atomic import atomic_text_writer
from rigctl.storage.text import printable

_ROWS_PER_WRITE = 16384
_OTHER_DELIMITERS = {";": "';' (semicolon)", "\t": "a tab", "|": "'|' (pipe)"}


class _Header:
    """What precedes the data rows: metadata, column names, and where the header line is."""

    def __init__(self, metadata: dict[str, str], names: list[str], line: int) -> None:
        self.metadata = metadata
        self.names = names
        self.line = line  # 1-based line number of the header row


def read_csv(path: str | Path) -> MeasuredRun:
    """Read one run from an exchange-format CSV file (strict; see the module docstring)."""
    src = Path(path)
    fast = _read_fast(src)
    if fast is None:
        return _read_slow(src)
    header, table = fast
    columns = {name: np.ascontiguousarray(table[:, j]) for j, name in enumerate(header.names)}
    del table
    try:
        _check_required_values(src, columns, None)
    except DataError:
        return _read_slow(src)  # names the line of the problem
    return _measured(src, header, columns)


def _read_slow(src: Path) -> MeasuredRun:
    lines = _read_lines(src)
    header = _parse_header(src, lines)
    rows = _Rows(lines, header.line)
    if not rows.lines:
        raise DataError("no data rows after the header", path=src, line=header.line)
    table = _parse_numbers(src, header, rows)
    columns = {name: np.ascontiguousarray(table[:, j]) for j, name in enumerate(header.names)}
    _check_required_values(src, columns, rows)
    return _measured(src, header, columns)


def _measured(src: Path, header: _Header, columns: dict[str, FloatArray]) -> MeasuredRun:
    extra = {name: arr for name, arr in columns.items() if name not in REQUIRED_COLUMNS}
    return MeasuredRun(
        t_s=columns["t_s"],
        x_stage_m=columns["x_stage_m"],
        fn_N=columns["fn_N"],
        ft_N=columns["ft_N"],
        d1_m=columns["d1_m"],
        d2_m=columns["d2_m"],
        extra=extra,
        metadata=header.metadata,
        source=str(src),
    )


def write_csv(path: str | Path, run: MeasuredRun) -> None:
    """Write ``run`` as an exchange-format CSV file, all or nothing.

    The run must satisfy the format (finite required columns, strictly increasing time): an invalid
    run raises :class:`DataError` before the target is touched.
    """
    dst = Path(path)
    run.validate()
    for key, value in run.metadata.items():
        _check_metadata_item(dst, key, value)
    columns = run.columns()
    for name in columns:
        if not name or "," in name or "\n" in name or name.startswith("#") or name != name.strip():
            raise DataError(f"column name {name!r} cannot be written to CSV", path=dst)
    if not dst.parent.is_dir():
        raise DataError("the output folder does not exist", path=dst)
    try:
        with atomic_text_writer(dst) as out:
            for key, value in run.metadata.items():
                out.write(f"# {key}: {value}\n")
            out.write(",".join(columns) + "\n")
            for text in _format_rows(list(columns.values())):
                out.write(text)
    except OSError as exc:
        raise DataError(f"cannot write: {exc.strerror or exc}", path=dst) from exc


# -- reading ---------------------------------------------------------------------------------------


def _read_fast(src: Path) -> tuple[_Header, FloatArray] | None:
    """Header and numbers of a well-formed file, parsed from the file without holding its text;
    None for anything irregular (the slow path then names the problem)."""
    if not src.is_file():
        return None
    head: list[str] = []
    try:
        with open(src, encoding="utf-8-sig") as fh:
            for line in fh:
                head.append(line.rstrip("\r\n"))
                stripped = line.strip()
                if stripped and not stripped.startswith("#"):
                    break
                if len(head) > 10_000:
                    return None
        header = _parse_header(src, head)
        with warnings.catch_warnings():
            # a header without rows: the line-by-line reader names it ("no data rows")
            warnings.filterwarnings("ignore", "loadtxt: input contained no data", UserWarning)
            table = np.loadtxt(src, delimiter=",", dtype=np.float64, comments=None, ndmin=2,
                               quotechar=None, skiprows=header.line, encoding="utf-8")
    except (DataError, ValueError, UnicodeDecodeError, OSError):
        return None
    if table.shape[0] == 0 or table.shape[1] != len(header.names):
        return None
    return header, np.asarray(table, dtype=np.float64)


def _read_lines(src: Path) -> list[str]:
    if not src.exists():
        raise DataError("no such file", path=src)
    if not src.is_file():
        raise DataError("not a file", path=src)
    raw = src.read_bytes()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise DataError(f"not UTF-8 text (byte {exc.start})", path=src, line=line) from None
    text = text.removeprefix("\ufeff")  # a byte-order mark some spreadsheet programs write
    if not text or text.isspace():
        raise DataError("empty file", path=src)
    return text.splitlines()


def _parse_header(src: Path, lines: list[str]) -> _Header:
    metadata: dict[str, str] = {}
    for index, line in enumerate(lines):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            body = stripped[1:].strip()
            key, sep, value = body.partition(":")
            if sep and key.strip():
                metadata[key.strip()] = value.strip()
            continue
        names = _split_header(src, line, index + 1)
        return _Header(metadata, names, index + 1)
    raise DataError("empty file: comment lines but no header row", path=src)


def _split_header(src: Path, line: str, line_no: int) -> list[str]:
    if "," not in line:
        for delimiter, label in _OTHER_DELIMITERS.items():
            if delimiter in line:
                raise DataError(
                    f"wrong delimiter: the header is separated by {label}; "
                    "the exchange format is comma-separated",
                    path=src,
                    line=line_no,
                )
    names = [name.strip() for name in line.split(",")]
    for position, name in enumerate(names, start=1):
        if not name:
            raise DataError(f"column {position} of the header has no name", path=src, line=line_no)
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise DataError("duplicate column name", path=src, line=line_no, column=printable(name))
        seen.add(name)
    missing = [name for name in REQUIRED_COLUMNS if name not in seen]
    if missing:
        listed = ", ".join(f"'{m}'" for m in missing)
        raise DataError(
            f"missing required column(s) {listed}; the header has {printable(', '.join(names))}",
            path=src,
            line=line_no,
            column=missing[0],
        )
    return names


class _Rows:
    """The non-blank lines after the header, and the file line number of each (1-based)."""

    def __init__(self, lines: list[str], header_line: int) -> None:
        after = lines[header_line:]
        self._blank = [i for i, line in enumerate(after) if not line or line.isspace()]
        self.lines = [line for line in after if line and not line.isspace()] if self._blank else after
        self._first_line = header_line + 1

    def line_number(self, row: int) -> int:
        """File line number of data row ``row`` (0-based among the non-blank rows)."""
        index = row
        for blank in self._blank:
            if blank <= index:
                index += 1
            else:
                break
        return self._first_line + index


def _parse_numbers(src: Path, header: _Header, rows: _Rows) -> FloatArray:
    n_cols = len(header.names)
    try:
        table = np.loadtxt(
            rows.lines, delimiter=",", dtype=np.float64, comments=None, ndmin=2, quotechar=None
        )
    except ValueError as exc:
        _locate_bad_value(src, header.names, rows)
        raise DataError(f"unreadable numbers: {exc}", path=src) from exc
    if table.shape[1] != n_cols:
        _locate_bad_value(src, header.names, rows)
        raise DataError(f"rows have {table.shape[1]} values, header has {n_cols}", path=src)
    return np.asarray(table, dtype=np.float64)


def _locate_bad_value(src: Path, names: list[str], rows: _Rows) -> None:
    """Slow pass: raise DataError at the first row or value the bulk parser could not take."""
    n_cols = len(names)
    for row, line in enumerate(rows.lines):
        line_no = rows.line_number(row)
        fields = line.split(",")
        if len(fields) != n_cols:
            for delimiter, label in _OTHER_DELIMITERS.items():
                if len(fields) < n_cols and delimiter in line:
                    raise DataError(
                        f"wrong delimiter: values separated by {label}; "
                        "the exchange format is comma-separated",
                        path=src,
                        line=line_no,
                    )
            raise DataError(
                f"expected {n_cols} comma-separated values, found {len(fields)}",
                path=src,
                line=line_no,
            )
        for name, field in zip(names, fields, strict=True):
            text = field.strip()
            if not text:
                raise DataError("empty value", path=src, line=line_no, column=printable(name))
            try:
                float(text)
            except ValueError:
                raise DataError(f"non-numeric value {text!r}", path=src, line=line_no,
                                column=printable(name)) from None


def _check_required_values(src: Path, columns: dict[str, FloatArray], rows: _Rows | None) -> None:
    """NaN or infinite required values and time order; ``rows`` None (the fast path): the error
    carries no line (the caller re-reads the text to name it)."""
    for name in REQUIRED_COLUMNS:
        bad = np.flatnonzero(~np.isfinite(columns[name]))
        if bad.size:
            i = int(bad[0])
            raise DataError(
                f"{float(columns[name][i])!r} is not allowed in a required column (NaN or infinite)",
                path=src,
                line=rows.line_number(i) if rows else None,
                column=name,
            )
    t = columns["t_s"]
    bad = np.flatnonzero(np.diff(t) <= 0.0)
    if bad.size:
        i = int(bad[0]) + 1
        raise DataError(
            f"time is not strictly increasing: {float(t[i])!r} s follows {float(t[i - 1])!r} s",
            path=src,
            line=rows.line_number(i) if rows else None,
            column="t_s",
        )


# -- writing ---------------------------------------------------------------------------------------


def _check_metadata_item(dst: Path, key: str, value: str) -> None:
    if not key or key != key.strip() or ":" in key or "\n" in key or "\r" in key:
        raise DataError(f"metadata key {key!r} cannot be written as '# key: value'", path=dst)
    if "\n" in value or "\r" in value or value != value.strip():
        raise DataError(f"metadata value of {key!r} has a line break or surrounding blanks", path=dst)


def _format_rows(columns: list[FloatArray]) -> Iterator[str]:
    """CSV text of the rows, in blocks; ``%r`` gives the shortest exactly-round-tripping text."""
    n_rows = columns[0].shape[0] if columns else 0
    table = np.column_stack(columns) if columns else np.empty((0, 0))
    row_format = ",".join(["%r"] * len(columns)) + "\n"
    for start in range(0, n_rows, _ROWS_PER_WRITE):
        block = table[start : start + _ROWS_PER_WRITE]
        yield (row_format * block.shape[0]) % tuple(block.ravel().tolist())
