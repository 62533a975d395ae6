"""Hostile input: markup in titles, notes, headers and file names is escaped
everywhere it appears; text cells of exported CSV cannot run as spreadsheet formulas; huge
files are refused; and property-based fuzzing of CSV and TOML texts never gets anything but
tcamlab's own errors out of the readers.
"""

from __future__ import annotations

import csv
import math
import re
import shutil
import tempfile
from html.parser import HTMLParser
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from tcamlab import io as tio
from tcamlab.cli import app
from tcamlab.config import load_experiment
from tcamlab.errors import TcamlabError
from tcamlab.pipeline import neutralise_csv

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()
SCRIPT = "<script>alert(1)<script>"


class _Page(HTMLParser):
    """Collects start tags, visible text, attribute values and comments."""

    def __init__(self, html: str):
        super().__init__(convert_charrefs=True)
        self.tags: dict[str, int] = {}
        self.text: list[str] = []
        self.attrs: list[str] = []
        self.comments: list[str] = []
        self.feed(html)
        self.close()

    def handle_starttag(self, tag, attrs):
        self.tags[tag] = self.tags.get(tag, 0) + 1
        self.attrs += [v or "" for _, v in attrs]

    def handle_data(self, data):
        self.text.append(data)

    def handle_comment(self, data):
        self.comments.append(data)

    @property
    def visible(self) -> str:
        return "".join(self.text)


def assert_inert(html: str, *visible: str) -> _Page:
    page = _Page(html)
    assert "script" not in page.tags, "a <script> element made it into the page"
    assert not any(a.strip().lower().startswith("javascript:") for a in page.attrs)
    for text in visible:
        assert text in page.visible, f"{text!r} is not shown as text"
    return page


def _hostile_static(lab: Path, runs: list[str], **fields) -> Path:
    text = (lab / "experiments/static.toml").read_text()
    listed = ", ".join(f"'../raw/{r}'" for r in runs)  # literal strings: no escapes
    text = re.sub(r"runs = \[[^\]]*\]", lambda m: f"runs = [{listed}]", text, flags=re.S)
    for key, value in fields.items():
        text = re.sub(rf"(?m)^{key} = .*$", lambda m, key=key, value=value: f"{key} = {value}", text)
    p = lab / "experiments" / "hostile.toml"
    p.write_text(text)
    return p


def _copy_run(lab: Path, name: str, src: str = "static_run1.csv") -> str:
    try:
        shutil.copy(lab / "raw" / src, lab / "raw" / name)
    except OSError:  # pragma: no cover - a file system without '<' in names
        pytest.skip(f"cannot create {name!r} here")
    return name


def test_markup_in_title_notes_and_run_names_is_escaped_in_html_and_pdf(lab):
    runs = [
        _copy_run(lab, f"{SCRIPT}.csv"),
        _copy_run(lab, "a--><script>b.csv", "static_run2.csv"),
        _copy_run(lab, "$\\frac$ _x.csv", "static_run3.csv"),  # mathtext, if parsed
        _copy_run(lab, "_hidden.csv", "static_run3.csv"),
    ]  # legend drops '_' labels
    exp = _hostile_static(
        lab,
        runs,
        title="\"<script>alert('title')</script> T\"",
        notes='"<img src=x onerror=alert(1)> & <script>n</script>"',
    )
    out = lab / "out"
    result = runner.invoke(app, ["validate", "static", str(exp), "--out", str(out)])
    assert result.exit_code == 0, result.output
    html = (out / "hostile/report.html").read_text()
    page = assert_inert(
        html,
        "<script>alert('title')</script> T",
        "<img src=x onerror=alert(1)> & <script>n</script>",
        SCRIPT,
        "a--><script>b",
        "$\\frac$ _x",
    )
    assert "img" not in page.tags
    # matplotlib's SVG comments carry legend text; they must stay comments
    assert all("<script" not in c for c in page.comments)
    # ... and show every run in the legend, even one whose name starts with '_' (four runs:
    # the legend groups them by what they show, naming each run)
    assert any("_hidden" in c and "measured" in c for c in page.comments)
    assert any("$\\frac$ _x" in c and "measured" in c for c in page.comments)
    from pypdf import PdfReader

    text = "".join(p.extract_text() for p in PdfReader(str(out / "hostile/report.pdf")).pages)
    assert "<script>alert('title')</script> T" in text
    assert SCRIPT in text


def test_markup_in_a_mapped_column_header(lab, monkeypatch):
    """A [columns] header with markup: used as data when found, escaped when reported."""
    import pandas as pd

    df = pd.read_csv(lab / "raw/static_run1.csv")
    df = df.rename(columns={"temperature_C": "<script>T</script>"})
    df.to_csv(lab / "raw/mapped.csv", index=False)
    exp = _hostile_static(lab, ["mapped.csv"])
    exp.write_text(exp.read_text() + '\n[columns]\ntemperature_C = "<script>T</script>"\n')
    out = lab / "out"
    result = runner.invoke(app, ["validate", "static", str(exp), "--out", str(out), "--format", "html"])
    assert result.exit_code == 0, result.output
    assert_inert((out / "hostile/report.html").read_text())

    # the same header missing from the file: the error in index.html is escaped text
    (lab / "raw/mapped.csv").write_text(df.rename(columns={"<script>T</script>": "T"}).to_csv(index=False))
    monkeypatch.chdir(lab)
    result = runner.invoke(app, ["report", "experiments/hostile.toml", "--out", "r"])
    assert result.exit_code == 2
    assert "column '<script>T</script>' (for temperature_C) not found" in result.output
    assert_inert(
        (lab / "r/index.html").read_text(), "column '<script>T</script>' (for temperature_C) not found"
    )


@pytest.mark.slow
def test_markup_in_experiment_names_and_titles_in_the_index(lab, monkeypatch):
    exp = _hostile_static(lab, ["static_run1.csv"], title='"<script>x</script>"')
    for name in ("x?y#z.toml", "javascript:alert(1).toml"):
        shutil.copy(exp, lab / "experiments" / name)
    monkeypatch.chdir(lab)
    result = runner.invoke(
        app,
        [
            "report",
            "experiments/hostile.toml",
            "experiments/x?y#z.toml",
            "experiments/javascript:alert(1).toml",
            "--out",
            "r",
        ],
    )
    assert result.exit_code == 0, result.output
    index = (lab / "r/index.html").read_text()
    assert_inert(index, "<script>x</script>")
    assert 'href="x%3Fy%23z/report.html"' in index
    assert 'href="javascript%3Aalert%281%29/report.html"' in index
    assert (lab / "r/x?y#z/report.html").exists()


# --- CSV formula injection ------------------------------------------------------------------


@pytest.mark.parametrize("prefix", ["=", "+", "-", "@"])
def test_run_names_in_predictions_csv_are_neutralised(lab, prefix):
    name = f"{prefix}HYPERLINK(1)"
    _copy_run(lab, f"{name}.csv")
    exp = _hostile_static(lab, [f"{name}.csv", "static_run2.csv"])
    out = lab / "out"
    result = runner.invoke(app, ["validate", "static", str(exp), "--out", str(out), "--format", "html"])
    assert result.exit_code == 0, result.output
    with open(out / "hostile/predictions.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    runs = {r["run"] for r in rows}
    assert runs == {"'" + name, "static_run2"}
    # negative numbers stay numbers: only text cells are neutralised
    values = [r["measured_displacement_mm"] for r in rows]
    assert any(v.startswith("-") for v in values)
    assert all(not v.startswith("'") for v in values)
    assert all(math.isfinite(float(v)) for v in values)
    for r in rows:
        for k, v in r.items():
            if k != "run" and v:
                float(v)  # every other cell is a plain number


def test_neutralise_csv_keeps_numbers_and_headers_safe():
    import pandas as pd

    df = pd.DataFrame(
        {"run": ["=1+1", "-x", "ok", "@a", "\tb"], "v": [-1.5, 2.0, -0.0, 3.0, 4.0], "=bad": [1, 2, 3, 4, 5]}
    )
    out = neutralise_csv(df)
    assert list(out["run"]) == ["'=1+1", "'-x", "ok", "'@a", "'\tb"]
    assert list(out["v"]) == [-1.5, 2.0, -0.0, 3.0, 4.0]
    assert list(out.columns) == ["run", "v", "'=bad"]


# --- huge files -------------------------------------------------------------------------------


def test_huge_file_is_refused_by_the_default_limit_without_being_read(lab):
    big = lab / "raw/huge.csv"
    with open(big, "wb") as fh:  # sparse: 3 GiB on paper, nothing on disk
        fh.write(b"temperature_C,displacement_mm\n")
        fh.truncate(3 * 1024**3)
    exp = _hostile_static(lab, ["huge.csv"])
    result = runner.invoke(app, ["validate", "static", str(exp), "--out", str(lab / "out")])
    assert result.exit_code == 2
    text = result.output.strip()
    assert len(text.splitlines()) == 1 and "Traceback" not in text
    assert "huge.csv: file is 3.00 GiB, larger than the limit of 2.00 GiB" in text
    assert "--max-bytes" in text
    assert not (lab / "out/hostile").exists()


# --- property-based fuzzing of the readers ---------------------------------------------------

_SEEDS = {k: (ROOT / "raw" / f"{k}_run1.csv").read_bytes().splitlines(keepends=True)[:40] for k in tio.KINDS}
_ODD = [
    "",
    " ",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e400",
    "-1e400",
    "1e308",
    "abc",
    "1,5",
    '"',
    "#",
    "\x00",
    "\ufeff",
    "\u00b0",
    "-0",
    "0x1",
    "1e",
    "--1",
    "9" * 330,
    "\U0001f600",
]


@st.composite
def mutated_csv(draw):
    """A shipped run (first 40 lines) with structured and byte-level mutations."""
    kind = draw(st.sampled_from(tio.KINDS))
    lines = [line.decode() for line in _SEEDS[kind]]
    header, rows = lines[0].rstrip("\n").split(","), [r.rstrip("\n").split(",") for r in lines[1:]]
    for _ in range(draw(st.integers(0, 4))):
        op = draw(
            st.sampled_from(
                ["cell", "swap", "dup_header", "drop_col", "drop_rows", "dup_row", "reverse", "rename"]
            )
        )
        if op == "cell" and rows:
            r = draw(st.integers(0, len(rows) - 1))
            if not rows[r]:
                continue
            c = draw(st.integers(0, len(rows[r]) - 1))
            rows[r][c] = draw(st.one_of(st.sampled_from(_ODD), st.text(max_size=5), st.floats().map(repr)))
        elif op == "swap" and len(header) > 1:
            i, j = draw(st.permutations(range(len(header))))[:2]
            header[i], header[j] = header[j], header[i]
        elif not header:
            continue
        elif op == "dup_header":
            header[draw(st.integers(0, len(header) - 1))] = header[0]
        elif op == "drop_col":
            c = draw(st.integers(0, len(header) - 1))
            header.pop(c)
            rows = [r[:c] + r[c + 1 :] for r in rows]
        elif op == "drop_rows":
            rows = rows[: draw(st.integers(0, len(rows)))]
        elif op == "dup_row" and rows:
            rows.insert(1, list(rows[0]))
        elif op == "reverse":
            rows.reverse()
        elif op == "rename":
            header[draw(st.integers(0, len(header) - 1))] = draw(st.text(max_size=8))
    sep = draw(st.sampled_from([",", ";", "\t"]))
    text = "\n".join([sep.join(header)] + [sep.join(r) for r in rows]) + "\n"
    if sep == ";" and draw(st.booleans()):
        text = text.replace(".", ",")
    encoding = draw(st.sampled_from(["utf-8", "utf-8-sig", "latin-1"]))
    data = bytearray(text.encode(encoding, errors="replace"))
    for _ in range(draw(st.integers(0, 3))):
        op = draw(st.sampled_from(["truncate", "flip", "insert"]))
        pos = draw(st.integers(0, len(data)))
        if op == "truncate":
            del data[pos:]
        elif op == "flip" and pos < len(data):
            data[pos] = draw(st.integers(0, 255))
        else:
            data[pos:pos] = draw(st.binary(min_size=1, max_size=8))
    return kind, bytes(data), draw(st.booleans())


def _check_run(run: tio.RunData, kind: str) -> None:
    df = run.data
    assert {tio.VARIABLE_MAP[c][0] for c in tio.REQUIRED[kind]} <= set(df.columns)
    assert df.shape[0] >= tio.MIN_ROWS[kind]
    assert all(str(t) == "float64" for t in df.dtypes)
    import numpy as np

    assert np.isfinite(df.to_numpy()).all()


@pytest.mark.slow
@settings(
    max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large]
)
@given(mutated_csv())
def test_fuzz_csv_loads_or_raises_a_tcamlab_error(case):
    kind, data, drop_na = case
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "run.csv"
        p.write_bytes(data)
        try:
            run = tio.read_run(p, kind, drop_na=drop_na)
        except TcamlabError as exc:
            assert "\n" not in exc.one_line()
            return
        _check_run(run, kind)


_TOML_SEEDS = {p.stem: p.read_text() for p in sorted((ROOT / "experiments").glob("*.toml"))}
_KEYS = [
    "kind",
    "title",
    "runs",
    "notes",
    "preset",
    "coil_length_mm",
    "fiber_diameter_mm",
    "max_volume_fraction",
    "thread_plies",
    "load_g",
    "ambient_C",
    "spring_constant_N_per_m",
    "segment_lengths_mm",
    "bogus",
    "titel",
    "rmse_mm",
    "r2_min",
    "from",
    "unit",
    "scale",
    "time_s",
    "force_N",
    "seed",
    "generator",
]
_TOML_VALUES = st.one_of(
    st.sampled_from(
        [
            '""',
            '"static"',
            '"sensing"',
            '"thesis-tca"',
            '"thesis-tcs"',
            "0",
            "-1",
            "1e400",
            "nan",
            "inf",
            "-inf",
            "true",
            "[]",
            "[1, 2]",
            '["../raw/x.csv"]',
            '["../raw/static_run1.csv"]',
            '["../raw/sensing_run1.csv", "../raw/sensing_run2.csv"]',
            "{}",
            '{ from = "x", unit = "ms" }',
            '{ from = "t", scale = 0 }',
            "1979-05-27",
            "9223372036854775807",
            '"\\u0000"',
            '"<script>"',
            "[[1]]",
            '["../raw"]',
            '["/"]',
            '["../raw/\\u0000"]',
        ]
    ),
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.integers(-(10**20), 10**20).map(str),
)


@st.composite
def toml_texts(draw):
    """Either a shipped experiment file with text-level mutations, or one built from
    random (partly valid) keys, tables and values."""
    if draw(st.booleans()):
        text = _TOML_SEEDS[draw(st.sampled_from(sorted(_TOML_SEEDS)))]
        lines = text.splitlines()
        for _ in range(draw(st.integers(1, 3))):
            op = draw(st.sampled_from(["value", "delete", "insert", "truncate"]))
            i = draw(st.integers(0, len(lines) - 1))
            if op == "value" and "=" in lines[i]:
                lines[i] = lines[i].split("=", 1)[0] + "= " + draw(_TOML_VALUES)
            elif op == "delete":
                lines.pop(i)
            elif op == "insert":
                lines.insert(i, f"{draw(st.sampled_from(_KEYS))} = {draw(_TOML_VALUES)}")
            else:
                lines[i] = lines[i][: draw(st.integers(0, len(lines[i])))]
        data = ("\n".join(lines) + "\n").encode()
    else:
        top = [
            f"{k} = {draw(_TOML_VALUES)}"
            for k in draw(st.lists(st.sampled_from(["kind", "title", "runs", "notes", "bogus"]), unique=True))
        ]
        tables = []
        for table in draw(
            st.lists(
                st.sampled_from(["sample", "rig", "rig.uncertainty", "columns", "thresholds", "synthetic"]),
                unique=True,
            )
        ):
            body = [
                f"{k} = {draw(_TOML_VALUES)}"
                for k in draw(st.lists(st.sampled_from(_KEYS), unique=True, max_size=4))
            ]
            tables.append("\n".join([f"[{table}]"] + body))
        data = "\n".join(top + tables).encode()
    if draw(st.integers(0, 5)) == 0:
        pos = draw(st.integers(0, len(data)))
        data = data[:pos] + draw(st.binary(max_size=6)) + data[pos:]
    return data, draw(st.sampled_from([None, *tio.KINDS]))


@pytest.fixture(scope="module")
def fuzz_lab(tmp_path_factory):
    """experiments/ (empty) and raw/ with the first two runs of each kind."""
    root = tmp_path_factory.mktemp("fuzz")
    (root / "experiments").mkdir()
    shutil.copytree(ROOT / "raw", root / "raw", ignore=lambda _, names: [n for n in names if "run3" in n])
    return root


@settings(
    max_examples=250,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(case=toml_texts())
def test_fuzz_toml_loads_or_raises_a_tcamlab_error(fuzz_lab, case):
    data, expected = case
    p = fuzz_lab / "experiments" / "fuzz.toml"
    p.write_bytes(data)
    try:
        exp = load_experiment(p, expected_kind=expected)
        for run in exp.read_runs():
            _check_run(run, exp.kind)
    except TcamlabError as exc:
        assert "\n" not in exc.one_line()


def test_huge_experiment_file_is_refused(lab):
    exp = lab / "experiments/huge.toml"
    with open(exp, "wb") as fh:
        fh.write(b'kind = "static"\n')
        fh.truncate(50 * 1024**2)
    result = runner.invoke(app, ["validate", "static", str(exp)])
    assert result.exit_code == 2
    text = result.output.strip()
    assert len(text.splitlines()) == 1 and "Traceback" not in text
    assert "huge.toml: experiment file is 52428800 bytes, larger than the limit" in text


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    rows=st.lists(
        st.tuples(st.floats(-300, 300, allow_nan=False), st.floats(-50, 50, allow_nan=False)),
        min_size=10,
        max_size=40,
    ),
    sep=st.sampled_from([",", ";", "\t"]),
    title=st.booleans(),
)
def test_fuzz_headerless_logs_never_lose_their_first_row(rows, sep, title):
    """A log of numbers only is refused as it is, and read whole with header_row = 0: its first
    row is data, never a header (a vibrometer log once lost its first of 150,800 rows that way)."""
    text = ("Vibrometer log\n" if title else "") + "".join(
        f"{20 + i}{sep}{a!r}{sep}{b!r}\n" for i, (a, b) in enumerate(rows)
    )
    cols = {"header_row": 0, "temperature_C": {"from": 1}, "displacement_mm": {"from": 3}}
    if title:
        cols["skip_rows"] = 1
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "run.csv"
        p.write_text(text)
        if not title:
            with pytest.raises(TcamlabError, match="looks like data"):
                tio.read_run(p, "static")
        run = tio.read_run(p, "static", cols)
    assert len(run.data) == len(rows)
    assert run.data["temperature"].iloc[0] == 20.0
    assert run.data["displacement"].iloc[-1] == pytest.approx((rows[-1][1] - rows[0][1]) * 1e-3, abs=1e-12)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    header=st.lists(
        st.lists(
            st.sampled_from(list('aT( )[]"\\#=\x01\x7f\x1fµΩ°%,;') + ["mm", "Load", "Ohm"]), max_size=6
        ).map("".join)
        | st.text(max_size=8),
        min_size=1,
        max_size=5,
    ),
    units=st.booleans(),
    kind=st.sampled_from(tio.KINDS),
    sep=st.sampled_from([",", ";", "\t"]),
)
def test_fuzz_init_writes_valid_toml_or_a_tcamlab_error(header, units, kind, sep):
    """Whatever the header holds (quotes, backslashes, control characters, any script), the
    starter file is valid TOML, or init says in one line why it cannot write one."""
    import tomllib

    from tcamlab.starter import write_starter

    lines = [sep.join(h.replace(sep, " ") for h in header)]
    if units:
        lines.append(sep.join("mm" for _ in header))
    lines += [sep.join(str(i + j) for j in range(len(header))) for i in range(5)]
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "log.csv"
        p.write_text("\n".join(lines) + "\n", encoding="utf-8", errors="surrogatepass")
        try:
            res = write_starter(kind, p, Path(d) / "out" / "x.toml")
        except TcamlabError as exc:
            assert "\n" not in exc.one_line()
            return
        except UnicodeEncodeError:
            return
        tomllib.loads(res.path.read_text(encoding="utf-8"))
