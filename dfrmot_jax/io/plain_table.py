"""One-pass reading of *plain* delimited text tables, the KITTI readers' fast path.

The readers of :mod:`dfrmot_jax.io.kitti` and :mod:`dfrmot_jax.io.result_rows` split a file line by
line so that whatever they refuse is named by file, line and field. Nearly every file they read is
plain: printable ASCII lines (after an optional UTF-8 byte-order mark; LF or CRLF line ends), fields
separated by exactly one space (or by commas, with no space anywhere), no empty field (so no blank
line), the same number of fields on every line and a finite number in every numeric field. Such a
file is read here in one pass by pyarrow's C++ CSV reader, and the reader then applies its own
checks to the columns, the same code as on its line-by-line path; any problem, and any file that is
not plain (these functions return None), is read line by line, which names the problem. So nothing
here is a rule of its own: for a plain file, splitting each line on whitespace (or commas) gives
exactly pyarrow's fields, and pyarrow's number parsing is correctly rounded, as Python's ``float``
(the line reader's) is. A field pyarrow does not read as a finite number (``1_000``, ``nan``,
``nan(1)``, ...) sends the file to the line reader, whose rules for it hold.

Why pyarrow, measured on the 21 KITTI ``label_02`` files (65k rows x 17 fields, on this repo's
2-core machine): the line reader took ~0.10 s, ``pyarrow.csv.read_csv`` ~0.023 s, pandas'
C ``read_csv`` ~0.031 s, ``np.loadtxt`` ~0.037 s, and splitting the whole text at once, then
converting with numpy, ~0.12 s.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Iterator, Sequence

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

__all__ = ["plain_text", "first_line", "plain_columns", "joined_columns", "read_ahead"]

_PRINTABLE = bytes(range(0x20, 0x7F)) + b"\n"
_BOM = b"\xef\xbb\xbf"


def plain_text(path) -> bytes | None:
    """The bytes of ``path`` (without a leading UTF-8 byte-order mark; CRLF line ends as LF) when they
    are non-empty printable ASCII and newlines only (no tab, no lone CR, ...): the text :func:`plain_columns`
    may read. None otherwise, and when the file cannot be read."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError:
        return None
    if data.startswith(_BOM):
        data = data[len(_BOM):]
    if b"\r" in data:
        data = data.replace(b"\r\n", b"\n")     # CRLF line ends; a lone CR stays, and is refused below
    if not data or data.translate(None, _PRINTABLE):
        return None
    return data


def first_line(data: bytes) -> str:
    """The first line of :func:`plain_text`'s bytes, as str."""
    end = data.find(b"\n")
    return (data if end < 0 else data[:end]).decode("ascii")


def plain_columns(data: bytes, sep: str | None, ncols: int, string_columns: Sequence[int] = (),
                  threads: bool = False) -> list | None:
    """The ``ncols`` fields of every line of ``data`` (:func:`plain_text`'s bytes), one array a field:
    [R] object str for the indices in ``string_columns``, [R] float64 for the others (R lines).

    sep: ``","`` or None (one space). None unless every line has exactly ``ncols`` fields, none of
    them empty, and every numeric field is a finite number pyarrow reads (``nan``, ``inf`` and the
    like go to the line readers, whose rules for them differ); with commas, None when the text
    has a space (fields the line readers would strip). With one space between fields and none
    empty, there is no blank line, no space at the start or end of a line nor two in a row: each
    line's whitespace-split fields are these. threads: let pyarrow parse blocks of the text in its
    own threads (for a large text: :func:`joined_columns`). A string column is read
    dictionary-encoded (its few distinct names made into str once, shared by the rows).
    """
    if sep == "," and b" " in data:
        return None
    names = [str(i) for i in range(ncols)]
    strings = set(string_columns)
    types = {n: pa.dictionary(pa.int32(), pa.string()) if i in strings else pa.float64() for i, n in enumerate(names)}
    try:
        table = pacsv.read_csv(
            pa.py_buffer(data),
            read_options=pacsv.ReadOptions(column_names=names, use_threads=threads),
            parse_options=pacsv.ParseOptions(delimiter=sep or " ", quote_char=False, ignore_empty_lines=False),
            convert_options=pacsv.ConvertOptions(column_types=types, null_values=[], strings_can_be_null=False,
                                                 quoted_strings_can_be_null=False),
        )
    except pa.ArrowException:      # whatever pyarrow refuses, the line reader reads (and names)
        return None
    out = []
    for i in range(ncols):
        col = table.column(i)
        if col.null_count:
            return None
        if i in strings:
            arr = _decoded(col)
            if arr is None:
                return None
        else:
            arr = np.asarray(col.to_numpy(), dtype=np.float64)
            if not np.isfinite(arr).all():
                return None
        out.append(arr)
    return out


def _decoded(col) -> np.ndarray | None:
    """A dictionary-encoded string column (each block with its own dictionary) -> [R] object str, the
    rows of one name sharing one str; None when a row's name is empty."""
    names: dict[str, int] = {}
    codes = []
    for chunk in col.chunks:
        words = chunk.dictionary.to_pylist()
        if "" in words:
            return None
        local = np.asarray([names.setdefault(w, len(names)) for w in words] or [0], dtype=np.int64)
        codes.append(local[np.asarray(chunk.indices.to_numpy(), dtype=np.int64)])
    table = np.empty(len(names), dtype=object)
    table[:] = list(names)
    return table[np.concatenate(codes)] if codes else np.empty(0, dtype=object)


def joined_columns(texts: Sequence[bytes], sep: str | None, ncols: int,
                   string_columns: Sequence[int] = ()) -> tuple[list, np.ndarray] | None:
    """:func:`plain_columns` of one or several texts (each :func:`plain_text`'s bytes) in one parse
    (several: pyarrow's threads take its blocks): (the columns of all their lines, one text after the other; [n + 1]
    int64 the first line of each text and the total). None where :func:`plain_columns` of the joined
    text is None. A text's lines are its own: it ends with a newline, or one is added after it.

    Why one parse: the 21 KITTI ``label_02`` files (9.2 MB) take ~39 ms as 21 parses and ~17 ms
    as one on this repo's 2-core machine."""
    texts = [t if t.endswith(b"\n") else t + b"\n" for t in texts]
    starts = np.zeros(len(texts) + 1, dtype=np.int64)
    np.cumsum([np.count_nonzero(np.frombuffer(t, np.uint8) == 10) for t in texts], out=starts[1:])   # (3x bytes.count)
    cols = plain_columns(b"".join(texts), sep, ncols, string_columns, threads=len(texts) > 1)
    return None if cols is None else (cols, starts)


def read_ahead(reader: Callable, paths: Sequence, threads: int = 2) -> Iterator:
    """``reader(path)`` for each of ``paths``, in order, the files read ahead from this call on in
    ``threads`` threads while the caller works on other things or on the earlier files: pyarrow's
    parser releases Python's lock, so two files parse at once. A reader's error is raised when its
    file's turn comes, as a plain loop would raise it; what the caller does not take is cancelled
    when the iterator is closed."""
    ex = ThreadPoolExecutor(max(1, threads))
    futures = [ex.submit(reader, p) for p in paths]
    ex.shutdown(wait=False)             # (the submitted reads still run; the threads end after them)

    def results():
        try:
            for f in futures:
                yield f.result()
        finally:
            for f in futures:
                f.cancel()

    return results()
