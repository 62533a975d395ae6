"""Tests for tcamlab.report: HTML/PDF rendering, escaping, determinism, atomic writes."""

from __future__ import annotations

import io
import os
import subprocess
import sys
from html.parser import HTMLParser

import pytest

from tcamlab.errors import TcamlabError
from tcamlab.report import (
    Cell,
    Document,
    Figure,
    IndexDocument,
    IndexEntry,
    Section,
    Table,
    atomic_write_bytes,
    atomic_write_text,
    format_cell,
)
from tcamlab.report.figures import figure_to_png, figure_to_svg, new_figure
from tcamlab.report.html import render_html, render_index_html
from tcamlab.report.pdf import render_combined_pdf, render_pdf

pypdf = pytest.importorskip("pypdf")

EVIL_TITLE = "<script>alert(1)</script> TCAM report"
EVIL_COLUMN = "<b>& stress"
EVIL_NOTE = "creep <img src=x onerror=alert(2)> detected"


class _Collector(HTMLParser):
    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tags: list[str] = []
        self.attrs: list[tuple[str, dict[str, str | None]]] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        self.attrs.append((tag, dict(attrs)))

    def handle_startendtag(self, tag, attrs):
        self.handle_starttag(tag, attrs)

    def handle_data(self, data):
        self.text.append(data)

    def count(self, tag: str) -> int:
        return self.tags.count(tag)

    def ids(self) -> list[str]:
        return [a["id"] for _, a in self.attrs if a.get("id") is not None]

    def all_text(self) -> str:
        return "".join(self.text)


def _parse(html: str) -> _Collector:
    parser = _Collector()
    parser.feed(html)
    parser.close()
    return parser


def _make_figure(k: int):
    fig, ax = new_figure()
    ax.plot([0.0, 1.0, 2.0, 3.0], [0.0, 0.5 * k, 1.5, 2.0 + k], "o-", label=f"run {k} <x>")
    ax.set_xlabel("temperature [°C]")
    ax.set_ylabel("strain ε [%]")
    ax.set_title(f"figure {k}")
    ax.legend()
    return fig


def _make_doc() -> Document:
    table = Table(
        columns=["sample", EVIL_COLUMN, "σ [MPa]", "ok"],
        rows=[
            ["A1", 1.23456789, None, True],
            [Cell("B2", href="javascript:alert(3)"), float("nan"), 7, False],
            [Cell("C3", status="warn", href="runs/c3.html"), 2.5e-7, 12345678, True],
        ],
        caption="Fit <summary> & residuals",
    )
    figs = [
        Figure(_make_figure(1), caption="Stroke vs temperature <1>", alt="stroke plot"),
        Figure(_make_figure(2), caption="Second figure & more"),
    ]
    return Document(
        title=EVIL_TITLE,
        subtitle="sample <S-01>",
        sections=[
            Section(
                heading="Results <h2>",
                paragraphs=["First paragraph.\nSecond line & more."],
                notes=[EVIL_NOTE],
                tables=[table],
                figures=figs[:1],
                subsections=[Section(heading="Details", figures=figs[1:])],
            ),
            Section(heading="Empty section"),
        ],
        metadata={
            "tool": "tcamlab 0.1.0",
            "command": 'tcamlab report --out "<x>"',
            "input.sha256": "ab" * 32,
        },
        synthetic_banner="SYNTHETIC DATA <not measured>",
    )


@pytest.fixture(scope="module")
def doc() -> Document:
    return _make_doc()


@pytest.fixture(scope="module")
def html(doc) -> str:
    return render_html(doc)


@pytest.fixture(scope="module")
def pdf(doc) -> bytes:
    return render_pdf(doc)


# ---------------------------------------------------------------- document


def test_format_cell_rules():
    assert format_cell(None).text == "\u2013"
    assert format_cell(True) == Cell("pass", "pass")
    assert format_cell(False) == Cell("FAIL", "fail")
    assert format_cell(12345678).text == "12345678"
    assert format_cell(1.23456789).text == "1.235"
    assert format_cell(1.5, "{:.2f}").text == "1.50"
    assert format_cell(float("nan")).text == "NaN"
    assert format_cell("x<y").text == "x<y"
    c = Cell("t", "warn")
    assert format_cell(c) is c


def test_invalid_inputs_rejected():
    with pytest.raises(ValueError, match="row 1"):
        Table(["a", "b"], [[1, 2], [3]])
    with pytest.raises(ValueError):
        Cell("x", status="ok")
    with pytest.raises(ValueError):
        IndexEntry("n", "t", "k", "passed", {})


def test_section_defaults_not_shared():
    a, b = Section("a"), Section("b")
    assert a.paragraphs is not b.paragraphs
    assert Document("x").metadata is not Document("y").metadata


# ---------------------------------------------------------------- figures


def test_figure_svg_is_inlinable_and_deterministic():
    fig = _make_figure(1)
    svg = figure_to_svg(fig, index=3)
    assert svg.lstrip().startswith("<svg")
    assert "<?xml" not in svg and "DOCTYPE" not in svg and "<metadata" not in svg
    assert figure_to_svg(fig, index=3) == svg
    p = _parse(svg)
    assert all(i.startswith("svg3-") for i in p.ids())
    assert len(p.ids()) == len(set(p.ids()))
    png = figure_to_png(fig)
    assert png.startswith(b"\x89PNG")
    assert figure_to_png(fig) == png


def test_figures_module_import_is_cheap():
    code = (
        "import sys, tcamlab.report, tcamlab.report.figures, tcamlab.report.document;"
        "bad=[m for m in ('matplotlib','reportlab','jinja2') if m in sys.modules];"
        "assert not bad, bad"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


# ---------------------------------------------------------------- HTML


def test_html_escapes_user_strings(html):
    p = _parse(html)
    assert "script" not in p.tags
    assert "img" not in p.tags  # the note's <img onerror> must stay text
    assert "b" not in p.tags  # the column name's <b> must stay text
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    text = p.all_text()
    assert EVIL_TITLE in text
    assert EVIL_COLUMN in text
    assert EVIL_NOTE in text
    assert "Fit <summary> & residuals" in text
    assert "SYNTHETIC DATA <not measured>" in text
    assert 'tcamlab report --out "<x>"' in text
    assert "javascript:" not in html


def test_html_strips_control_characters():
    out = render_html(Document("a\x00b\x07c", metadata={"k": "v\x1b"}))
    assert "\x00" not in out and "\x07" not in out and "\x1b" not in out
    assert "<title>abc</title>" in out


def test_html_structure_counts(html):
    p = _parse(html)
    assert p.count("svg") == 2
    assert p.count("figure") == 2
    assert p.count("figcaption") == 2
    tables = [a for tag, a in p.attrs if tag == "table"]
    assert len(tables) == 2  # the data table + the provenance table
    data_tables = [a for a in tables if "provenance" not in (a.get("class") or "")]
    assert len(data_tables) == 1
    # 4 data-table headers + 2 provenance headers
    assert p.count("th") == 6
    # 3 data rows + 3 metadata rows, plus the two header rows
    assert p.count("tr") == 3 + 3 + 2
    assert p.count("h1") == 1
    assert p.count("h2") == 3  # two sections + provenance
    assert p.count("h3") == 1
    statuses = [a.get("class") for tag, a in p.attrs if tag == "td" and a.get("class")]
    assert statuses.count("status-pass") == 2
    assert statuses.count("status-fail") == 1
    assert statuses.count("status-warn") == 1
    links = [a["href"] for tag, a in p.attrs if tag == "a" and "href" in a]
    assert "runs/c3.html" in links


def test_html_ids_unique_and_internal_refs_resolve(html):
    p = _parse(html)
    ids = p.ids()
    assert len(ids) == len(set(ids))
    idset = set(ids)
    refs = []
    for _, attrs in p.attrs:
        for key in ("href", "xlink:href"):
            value = attrs.get(key)
            if value and value.startswith("#"):
                refs.append(value[1:])
    assert refs, "expected TOC links and SVG <use> references"
    missing = [r for r in refs if r not in idset]
    assert not missing


def test_html_is_self_contained(html):
    p = _parse(html)
    for tag in ("link", "script", "iframe", "img", "object", "embed"):
        assert tag not in p.tags
    for _, attrs in p.attrs:
        assert "src" not in attrs
    assert "http-equiv" in html  # CSP meta tag


def test_html_deterministic(doc, html):
    assert render_html(doc) == html
    assert render_html(_make_doc()) == html


def test_index_html():
    index = IndexDocument(
        title="Batch <2024>",
        entries=[
            IndexEntry(
                "run-01", "Static <fit>", "static", "pass", {"rmse": "0.012"}, link="run-01/report.html"
            ),
            IndexEntry(
                "run-02",
                "Dynamic",
                "dynamic",
                "fail",
                {"rmse": "0.5", "lag": "3 s"},
                link="javascript:alert(1)",
            ),
            IndexEntry("run-03", "Broken", "static", "error", {}, link=None, error="InputError: bad row <7>"),
        ],
        metadata={"tool": "tcamlab"},
    )
    out = render_index_html(index)
    p = _parse(out)
    assert "script" not in p.tags
    text = p.all_text()
    assert "Batch <2024>" in text and "InputError: bad row <7>" in text
    links = [a["href"] for tag, a in p.attrs if tag == "a"]
    assert links == ["run-01/report.html"]
    headers = [a for tag, a in p.attrs if tag == "th"]
    assert len(headers) == 4 + 2 + 2  # fixed (experiment, kind, status, warnings) + metrics + provenance
    classes = [a.get("class") for tag, a in p.attrs if tag == "td"]
    assert {"status-pass", "status-fail", "status-error"} <= set(classes)
    # a kind's name never wraps mid-word ("selfsensin / g" at 1280 px before)
    assert classes.count("kind") == 3 and "table.data td.kind { white-space: nowrap; }" in out
    assert render_index_html(index) == out


# ---------------------------------------------------------------- PDF


def _reader(data: bytes):
    return pypdf.PdfReader(io.BytesIO(data))


def _page_has_image(page) -> bool:
    resources = page.get("/Resources") or {}
    xobjects = resources.get("/XObject")
    if not xobjects:
        return False
    xobjects = xobjects.get_object()
    return any(xobjects[name].get_object().get("/Subtype") == "/Image" for name in xobjects)


def test_pdf_content(pdf):
    assert pdf.startswith(b"%PDF-")
    reader = _reader(pdf)
    assert len(reader.pages) >= 1
    text = "\n".join(page.extract_text() for page in reader.pages)
    assert EVIL_TITLE in text
    assert EVIL_COLUMN in text
    assert "sample" in text and "σ [MPa]" in text
    assert "SYNTHETIC DATA <not measured>" in text
    assert "Provenance" in text
    assert f"Page 1 of {len(reader.pages)}" in text
    images = sum(_page_has_image(page) for page in reader.pages)
    assert images >= 1
    assert reader.metadata.title == EVIL_TITLE
    titles = [o.title for o in reader.outline if not isinstance(o, list)]
    assert titles == [EVIL_TITLE]


def test_pdf_deterministic(doc, pdf):
    assert render_pdf(doc) == pdf
    assert render_pdf(_make_doc()) == pdf


def test_output_identical_across_processes(html, pdf):
    """Fresh interpreters (different hash seeds) produce the same bytes."""
    import hashlib

    here = os.path.dirname(os.path.abspath(__file__))
    code = (
        "import sys, hashlib; sys.path.insert(0, sys.argv[1]);"
        "from test_report_render import _make_doc;"
        "from tcamlab.report import render_html, render_pdf;"
        "d = _make_doc();"
        "print(hashlib.sha256(render_html(d).encode()).hexdigest());"
        "print(hashlib.sha256(render_pdf(d)).hexdigest())"
    )
    env = dict(os.environ, PYTHONHASHSEED="12345")
    out = subprocess.run(
        [sys.executable, "-c", code, here], check=True, env=env, capture_output=True, text=True
    ).stdout.split()
    assert out == [hashlib.sha256(html.encode()).hexdigest(), hashlib.sha256(pdf).hexdigest()]


def test_pdf_long_table_splits_with_header_repeated():
    rows = [[i, i * 0.5, f"row {i}"] for i in range(400)]
    doc = Document("Long", sections=[Section("Data", tables=[Table(["idx", "HEADERX", "label"], rows)])])
    reader = _reader(render_pdf(doc))
    assert len(reader.pages) > 3
    for page in reader.pages:
        assert "HEADERX" in page.extract_text()


def test_a_table_with_one_huge_figure_still_renders_every_column():
    """An estimator that diverged put a percentage of hundreds of digits in one cell of an 8-column table;
    scaled to the page, the other columns were 4 pt wide, less than their padding, and reportlab
    raised. Every column keeps a few characters now; the figure is cut, the PDF is written."""
    huge = "3" * 900 + ".0%"
    rows = [
        ["run1", huge, "1.2", "3.4", "5.6", "7.8", "9.0", "1.1"],
        ["pooled", "1", "2", "3", "4", "5", "6", "7"],
    ]
    header = ["run", "mean", "interval", "heating", "own", "laser", "withheld", "note"]
    doc = Document("Wide", sections=[Section("Data", tables=[Table(header, rows)])])
    text = _reader(render_pdf(doc)).pages[0].extract_text()
    assert "pooled" in text and "withheld" in text


def test_a_table_that_fits_a_page_starts_in_place_when_most_of_the_page_is_left():
    # a 40-row table (it fits a page) after a short summary: moved whole to page 2, it left page 1 blank
    rows = [[i, f"figure {i}", 0.5] for i in range(40)]
    doc = Document(
        "Benchmark",
        sections=[
            Section("Summary", paragraphs=["One line."] * 3),
            Section("Families", tables=[Table(["family", "FIGUREHEAD", "result"], rows)]),
        ],
    )
    first = _reader(render_pdf(doc)).pages[0].extract_text()
    assert "FIGUREHEAD" in first and "figure 0" in first


def test_combined_pdf(doc, pdf):
    other = Document("Second report", sections=[Section("Only", paragraphs=["hello"])])
    other_pdf = render_pdf(other)
    index = IndexDocument(
        "All runs",
        [
            IndexEntry("a", EVIL_TITLE, "static", "pass", {"rmse": "0.1"}, link="a.html"),
            IndexEntry("b", "Second report", "static", "error", {}, error="boom <x>"),
        ],
    )
    combined = render_combined_pdf([doc, other], index)
    reader = _reader(combined)
    n_parts = len(_reader(pdf).pages) + len(_reader(other_pdf).pages)
    assert len(reader.pages) >= n_parts + 1
    titles = [o.title for o in reader.outline if not isinstance(o, list)]
    assert titles == ["All runs", EVIL_TITLE, "Second report"]
    assert "boom <x>" in reader.pages[0].extract_text()
    assert render_combined_pdf([doc, other], index) == combined
    # without an index, reports still start on their own pages
    assert len(_reader(render_combined_pdf([doc, other], None)).pages) >= n_parts


# ---------------------------------------------------------------- atomic writes


def _leftovers(directory) -> list[str]:
    return [p.name for p in directory.iterdir() if p.name.endswith(".tmp")]


def test_atomic_write_creates_parents_and_leaves_no_temp(tmp_path):
    target = tmp_path / "a" / "b" / "report.html"
    atomic_write_text(target, "héllo\n")
    assert target.read_bytes() == "héllo\n".encode()
    atomic_write_bytes(target, b"second")
    assert target.read_bytes() == b"second"
    assert _leftovers(target.parent) == []
    assert sorted(p.name for p in target.parent.iterdir()) == ["report.html"]


def test_atomic_write_interrupted_keeps_original(tmp_path, monkeypatch):
    target = tmp_path / "report.pdf"
    target.write_bytes(b"original")

    def boom(src, dst):
        raise RuntimeError("interrupted")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(RuntimeError, match="interrupted"):
        atomic_write_bytes(target, b"new content")
    assert target.read_bytes() == b"original"
    assert _leftovers(tmp_path) == []


def test_atomic_write_os_error_becomes_tcamlab_error(tmp_path, monkeypatch):
    target = tmp_path / "report.html"
    target.write_text("original")

    def fail(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(TcamlabError, match="report.html"):
        atomic_write_text(target, "new")
    assert target.read_text() == "original"
    assert _leftovers(tmp_path) == []


def test_atomic_write_keeps_existing_permissions(tmp_path):
    target = tmp_path / "f.txt"
    target.write_text("x")
    os.chmod(target, 0o640)
    atomic_write_text(target, "y")
    assert (target.stat().st_mode & 0o777) == 0o640
