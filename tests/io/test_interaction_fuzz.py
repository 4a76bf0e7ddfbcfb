"""Property-based tests: the interaction reader survives any bytes.

Every mutated interaction folder either reads as a valid Interaction or raises
vei.errors.InputError (a clear message naming the file); never another exception.
Deterministic (``derandomize=True``): the same cases run in CI every time.
Cases: 300 + 300 + 250 + 150 = 1,000 in this module.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.helpers_interaction import make_interaction
from vei.errors import InputError
from vei.io.interaction import read_interaction
from vei.types import Interaction

FILES = ("interaction.json", "ego.csv", "annotations.csv", "ground_truth.csv")
SETTINGS = dict(
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


@pytest.fixture(scope="module")
def base() -> Path:
    root = Path(tempfile.mkdtemp(prefix="vei-fuzz-"))
    folder = make_interaction(root)
    yield folder
    shutil.rmtree(root, ignore_errors=True)


def _check(folder: Path) -> None:
    """read_interaction gives an Interaction or an InputError that names a file."""
    try:
        result = read_interaction(folder)
    except InputError as exc:
        assert str(exc).strip()
        assert exc.path is not None
        return
    assert isinstance(result, Interaction)
    assert len(result.ego) >= 2


class _Copy:
    def __init__(self, base: Path) -> None:
        self.tmp = Path(tempfile.mkdtemp(prefix="vei-fuzz-case-"))
        self.folder = self.tmp / "i"
        shutil.copytree(base, self.folder)

    def __enter__(self) -> Path:
        return self.folder

    def __exit__(self, *exc) -> None:
        shutil.rmtree(self.tmp, ignore_errors=True)


_mutation = st.one_of(
    st.tuples(st.just("flip"), st.integers(0, 10**6), st.integers(1, 255)),
    st.tuples(st.just("insert"), st.integers(0, 10**6), st.binary(min_size=1, max_size=12)),
    st.tuples(st.just("delete"), st.integers(0, 10**6), st.integers(1, 40)),
    st.tuples(st.just("truncate"), st.integers(0, 10**6), st.just(0)),
)


def _mutate(data: bytes, ops) -> bytes:
    b = bytearray(data)
    for kind, pos, arg in ops:
        p = pos % (len(b) + 1)
        if kind == "flip" and b:
            b[p % len(b)] ^= arg
        elif kind == "insert":
            b[p:p] = arg
        elif kind == "delete":
            del b[p : p + arg]
        elif kind == "truncate":
            del b[p:]
    return bytes(b)


@settings(max_examples=300, **SETTINGS)
@given(name=st.sampled_from(FILES), ops=st.lists(_mutation, min_size=1, max_size=4))
def test_byte_mutations(base, name, ops):
    with _Copy(base) as folder:
        path = folder / name
        path.write_bytes(_mutate(path.read_bytes(), ops))
        _check(folder)


_json = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda kids: (
        st.lists(kids, max_size=4) | st.dictionaries(st.text(max_size=8), kids, max_size=4)
    ),
    max_leaves=12,
)


@settings(max_examples=300, **SETTINGS)
@given(key=st.sampled_from(["format", "id", "source", "start_time_utc", "y_axis",
                            "annotation_rate_hz", "notes", "extra"]), value=_json)  # fmt: skip
def test_json_values(base, key, value):
    with _Copy(base) as folder:
        path = folder / "interaction.json"
        doc = json.loads(path.read_text())
        doc[key] = value
        path.write_text(json.dumps(doc))
        _check(folder)


_cell = st.one_of(
    st.sampled_from(["", "nan", "NaN", "inf", "-inf", "1e999", "-0", "0", "1e-320", "9" * 400,
                     "abc", '"', "'", ",", "\n", "\r\n", "\x00", "2021-02-09T12:00:00Z",
                     "2021-02-09T12:00:00", "-1", "360.0001", "1,5", " 3 "]),
    st.text(max_size=12),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(min_value=-(10**30), max_value=10**30).map(str),
)  # fmt: skip


@settings(max_examples=250, **SETTINGS)
@given(name=st.sampled_from(FILES[1:]), row=st.integers(0, 100), col=st.integers(0, 10), cell=_cell)
def test_csv_cells(base, name, row, col, cell):
    with _Copy(base) as folder:
        path = folder / name
        lines = path.read_text().split("\n")
        r = row % max(1, len(lines) - 1)
        cells = lines[r].split(",")
        cells[col % len(cells)] = cell
        lines[r] = ",".join(cells)
        path.write_text("\n".join(lines), encoding="utf-8", errors="surrogatepass")
        _check(folder)


@settings(max_examples=150, **SETTINGS)
@given(depth=st.integers(1, 200_000), opener=st.sampled_from(["[", '{"a":']))
def test_nested_json_is_an_input_error(base, depth, opener):
    """Deeply nested JSON (RecursionError in json.loads) is a clear InputError."""
    with _Copy(base) as folder:
        (folder / "interaction.json").write_text(opener * depth)
        with pytest.raises(InputError):
            read_interaction(folder)


def test_deeply_nested_interaction_json_message(base):
    with _Copy(base) as folder:
        (folder / "interaction.json").write_text("[" * 100_000 + "]" * 100_000)
        with pytest.raises(InputError, match="nested too deeply"):
            read_interaction(folder)
