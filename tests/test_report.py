"""The report of everything: present studies show their tables and figures, absent ones say so."""

from qmt_drake.apps.report import Section, build_report, markdown_to_html, table_cells


def test_report_shows_what_ran_and_names_what_did_not(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "table.md").write_text("| plan | T0 [s] |\n|---|---|\n| GA | 1.6893 |\n")
    (tmp_path / "a" / "fig.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    (tmp_path / "a" / "run.html").write_text("<html></html>")
    sections = [Section("Study A", "python -m studies.a", "a", seed="Thesis: 1.716 s", tables=("table.md",)),
                Section("Study B", "python -m studies.b", "b")]
    html = build_report(tmp_path, sections).read_text()
    assert "<td>1.6893</td>" in html and "src='a/fig.png'" in html and "href='a/run.html'" in html
    assert "Thesis: 1.716 s" in html and "python -m studies.a" in html
    assert "Study B</a> (not run)" in html and "Not run: no results under" in html


def test_markdown_tables_lists_and_code():
    h = markdown_to_html("## T\n\n- a `x`\n- **b**\n\n| k | v |\n|:---|---:|\n| 1 | 2 |\n\n```\nq < 1\n```\n")
    assert "<h4>T</h4>" in h and "<li>a <code>x</code></li>" in h and "<li><b>b</b></li>" in h
    assert "<th>k</th>" in h and "<td>2</td>" in h and "<pre>q &lt; 1</pre>" in h


def _rows_of_cells(html_text: str) -> list[list[int]]:
    """Per rendered table, the number of cells of each row (header first)."""
    from html.parser import HTMLParser

    class Cells(HTMLParser):
        def __init__(self):
            super().__init__()
            self.tables: list[list[int]] = []

        def handle_starttag(self, tag, attrs):
            if tag == "table":
                self.tables.append([])
            elif tag == "tr":
                self.tables[-1].append(0)
            elif tag in ("td", "th"):
                self.tables[-1][-1] += 1

    p = Cells()
    p.feed(html_text)
    return p.tables


def test_a_literal_bar_in_a_header_keeps_every_column_in_place():
    md = "| type | max lateral joint \\|y\\| [m] | E |\n|---|---|---|\n| BP | 0.12 | 1.1884 |\n"
    h = markdown_to_html(md)
    assert _rows_of_cells(h) == [[3, 3]]
    assert "<th>max lateral joint |y| [m]</th>" in h and "misaligned" not in h
    assert table_cells("| a \\| b | c |") == ["a | b", "c"]


def test_a_misaligned_table_is_flagged_in_the_report_not_rendered_silently():
    h = markdown_to_html("| a | b |\n|---|---|\n| 1 | 2 | 3 |\n")
    assert "misaligned: rows [1]" in h


def test_every_table_of_the_docs_has_as_many_cells_in_each_row_as_in_its_header():
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    for md in [root / "README.md", *sorted((root / "docs").glob("*.md"))]:
        h = markdown_to_html(md.read_text())
        assert "misaligned" not in h, md.name
        for table in _rows_of_cells(h):
            assert len(set(table)) == 1, (md.name, table)


def test_the_report_shows_the_sweep_figures_and_the_planner_speed_table(tmp_path):
    from qmt_drake.apps.report import SECTIONS

    (tmp_path / "sweeps" / "ch4").mkdir(parents=True)
    (tmp_path / "sweeps" / "ch4" / "success_probability.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    (tmp_path / "success_probability.md").write_text("| case | p |\n|---|---|\n| a | 0.9 |\n")
    (tmp_path / "bench.md").write_text("| quantity | value |\n|---|---|\n| fitness evaluations per s | 4000 |\n")
    (tmp_path / "bench.json").write_text("{}")
    html = build_report(tmp_path, SECTIONS).read_text()
    assert "src='sweeps/ch4/success_probability.png'" in html
    assert "<td>fitness evaluations per s</td>" in html
