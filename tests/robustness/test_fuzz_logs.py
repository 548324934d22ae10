"""Fuzzing the log parsers: any line or file gives messages or the project's own error."""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ceamcl.errors import CeamclError

FUZZ = settings(
    max_examples=1000,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

# ----------------------------------------------------------------------------------- CARMEN
carmen = pytest.importorskip("ceamcl.io.carmen", reason="the CARMEN reader is not there yet")

NUMBER_TOKENS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-5, 400).map(str),
    st.sampled_from(["nan", "inf", "-inf", "1e999", "0x10", "", "--1", "1.2.3", "abc"]),
)
MESSAGES = ["FLASER", "RLASER", "ODOM", "ROBOTLASER1", "RAWLASER1", "PARAM", "#", "TRUEPOS"]


@st.composite
def carmen_lines(draw: st.DrawFn) -> str:
    head = draw(st.one_of(st.sampled_from(MESSAGES), st.text(max_size=10)))
    if head in ("FLASER", "RLASER") and draw(st.booleans()):
        n = draw(st.integers(0, 6))
        count = draw(st.sampled_from([n, n, n - 1, n + 1]))
        body = [str(count)] + [draw(NUMBER_TOKENS) for _ in range(n + 6 + draw(st.integers(0, 3)))]
    else:
        body = draw(st.lists(NUMBER_TOKENS, max_size=30))
    sep = draw(st.sampled_from([" ", "\t", "  "]))
    return sep.join([head, *body])


@FUZZ
@given(line=st.one_of(carmen_lines(), st.text(max_size=120)))
def test_fuzz_carmen_lines(line: str) -> None:
    try:
        carmen.parse_line(line, "fuzz.log", 7)
    except CeamclError as exc:
        assert "fuzz.log" in str(exc) and "7" in str(exc), f"no file and line in: {exc}"


@FUZZ
@given(lines=st.lists(st.one_of(carmen_lines(), st.text(max_size=60)), max_size=12))
def test_fuzz_carmen_files(lines: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.log"
        path.write_text("\n".join(lines), encoding="utf-8", errors="surrogatepass")
        try:
            carmen.read_carmen(path)
        except CeamclError as exc:
            assert "fuzz.log" in str(exc)
