"""The report of everything: present studies show their tables and figures, absent ones say so."""

from qmt_drake.apps.report import Section, build_report, markdown_to_html


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
