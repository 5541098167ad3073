"""One report of everything `make run` produced: out/report.html.

Each study is a `Section`: a title, the command that makes it, what the seed reports, and the
files it leaves under OUT (Markdown tables and notes, PNG figures, HTML recordings, JSON
summaries). The report shows, per section, the command, the seed's numbers, our tables, the
figures inline and links to the recordings and raw files; a study that has not run yet is listed
as missing with its command, so the report is honest about what it contains. Figures and
recordings are linked by relative path: open the report from inside OUT.

Markdown is rendered by a small converter (headings, paragraphs, lists, pipe tables, code) so
the report needs no extra package.
"""

from __future__ import annotations

import datetime as _dt
import html
import re
from dataclasses import dataclass
from pathlib import Path

from qmt_drake.outputs import write_text_atomic


@dataclass(frozen=True)
class Section:
    title: str
    command: str
    folder: str  # under OUT ("" for OUT itself)
    seed: str = ""  # what the seed reports, in Markdown
    tables: tuple = ()  # Markdown files (globs) shown inline
    figures: tuple = ("*.png",)  # PNG globs shown inline
    recordings: tuple = ("*.html",)  # HTML recordings, linked
    raw: tuple = ("*.json",)  # raw results, linked
    notes: str = ""  # our reading, in Markdown


SECTIONS: list[Section] = [
    Section("Seed 000, chapter 2: three-link arm, straight line", ".venv/bin/python -m studies.thesis_ch2",
            "thesis-ch2", seed="Thesis: T1 = 1.59 s, T2 = 0.51 s, T0 = 3.69 s; the moment touches its limit.",
            tables=("table.md",)),
    Section("Seed 000, chapter 3: two-link PTP, trapezoidal velocities", ".venv/bin/python -m studies.thesis_ch3",
            "thesis-ch3", seed="Thesis: T11 = 0.686 s, T21 = 0.565 s, omega_1m = 1.296 rad/s, T0 = 2.382 s.",
            tables=("table.md",)),
    Section("Seed 000, chapter 4: two-link arm through two via points", ".venv/bin/python -m studies.thesis_ch4",
            "thesis-ch4", seed="Thesis: T1 = 0.622 s, T2 = 0.532 s, T3 = 0.562 s, T0 = 1.716 s.",
            tables=("table.md",)),
    Section("Any number of vias: five vias, 6 genes x 12 bits", ".venv/bin/python -m studies.via_points",
            "via5-ch4", seed="Not in the thesis (its text suggests solving the 4N+4 system for general N).",
            tables=("table.md",)),
    Section("Co-simulation calibration against the slip experiments", ".venv/bin/python -m studies.cosim_calibration",
            "", seed="Thesis Tables 2.3 and 4.2: success up to 3.168e-5 N m (ch.2) and 0.633e-3 N m (ch.4).",
            tables=("cosim_calibration.md",), figures=("cosim_calibration_slip.png",), recordings=(),
            raw=("cosim_calibration.json",)),
    Section("Benchmark: GA against TOPP-RA, Ruckig and trajectory optimisation",
            ".venv/bin/qmt-drake benchmark --out out/benchmark", "benchmark", tables=("benchmark.md",)),
    Section("Planner speed", ".venv/bin/qmt-drake bench --out out", "", recordings=(), figures=(),
            tables=("bench.md",), raw=("bench.json",)),
    Section("Seed 001: energy-time optimal motions of a vertical 3-link arm (Ohsaka & Kurahashi 1988)",
            ".venv/bin/python -m studies.ohsaka_1988", "ohsaka_1988",
            seed="Fig. 3: z = 22766 / 20266 / 18815 for the patterns (+,-,-) / (+,+,+) / (-,+,-); "
                 "Fig. 4: T = 1.900 / 0.330 / 0.188 / 0.100 s for c2 = 1, 1e4, 1e5, 1e6; 500-800 iterations.",
            tables=("table.md",)),
    Section("Seed 002: a bottle on a tray carried by a CRANE-X7 arm", ".venv/bin/python -m studies.crane_tray",
            "crane_tray", seed="P-only gains (P = 800) with linear waypoint spacing: the bottle fell as the return "
                               "began; retuned PID with 1.5-power spacing: carried, about 5 s per move."),
    Section("Seed 002 through the servos as the firmware runs them: fastest carried transfer per friction and fill",
            ".venv/bin/python -m studies.tray_carried --out out", "tray_carried",
            seed="Not in the seed: the issue-20 re-measurement (TOPP-RA planned per bottle, its time scale bisected "
                 "until the co-simulation carries the bottle; goals shaped for the firmware's PID or streamed plain).",
            tables=("tray_carried.md",), figures=("tray_carried.png",), recordings=(), raw=("tray_carried.json",)),
    Section("Seed 003: task-oriented structural design by operability (Kotosaka et al. 1995)",
            ".venv/bin/python -m studies.kotosaka_1995", "kotosaka_1995",
            seed="Task-1: PB, PF, PT best (E = 1.2027, second link 0), BP 1.1884; Task-2: BF best (E = 2.0107), "
                 "BP 1.9951; without obstacles BP is best; about 60 generations (some 360).",
            tables=("*.md",)),
    Section("Spatial arms: a UR5 with a suction cup between two bins and with the thesis's magnet, a Panda with "
            "a cup on a tray", ".venv/bin/python -m studies.spatial_benchmark --out out (and studies.spatial_ga_seeds, "
            "studies.bench_spatial: the planning-speed tables)", "spatial",
            seed="Not in the seeds: two industrial arms from the `example-robot-data` package's URDFs, a "
                 "Universal Robots UR5 (6 revolute joints, about 0.85 m reach) moving a box with a suction cup "
                 "(the suction-cup transfer of Pham & Pham) and with the thesis's magnet, and a Franka Emika Panda "
                 "(7 joints) carrying an unfixed cup on a tray. Figures per scenario: the hand's limit ratio over "
                 "time per method (1 = the part is about to go), the methods' motion times against the TOPP-RA "
                 "bound coloured by the co-simulation's outcome, and with obstacles the clearance along each path.",
            tables=("*.md",), figures=("*.png",), recordings=(),
            raw=("ur5-suction-bins.json", "ur5-magnet-part.json", "panda-tray-cup.json")),
    Section("Success probability under uncertainty (Dask sweeps)",
            ".venv/bin/python -m studies.success_probability --cases 50 --robust thesis-ch4", "",
            tables=("success_probability.md",), figures=("sweeps/**/*.png",), recordings=(),
            raw=("success_probability.json",)),
]


def register(section: Section) -> None:
    """Add a study's section (studies of later seeds call this at import)."""
    if all(s.title != section.title for s in SECTIONS):
        SECTIONS.append(section)


def build_report(out_dir: Path, sections: list[Section] | None = None) -> Path:
    out = Path(out_dir)
    parts = [_HEAD, "<h1>qmt_drake: everything <code>make run</code> made</h1>",
             f"<p class=meta>Written {_dt.datetime.now().isoformat(timespec='seconds')} from <code>{html.escape(str(out))}"
             "</code>. Each section names the command that made it; figures are the PNG files beside this page.</p>",
             "<nav><ol>"]
    sections = SECTIONS if sections is None else sections
    for k, s in enumerate(sections):
        parts.append(f"<li><a href='#s{k}'>{html.escape(s.title)}</a>{'' if _present(out, s) else ' (not run)'}</li>")
    parts.append("</ol></nav>")
    for k, s in enumerate(sections):
        parts.append(_section_html(out, s, k))
    parts.append("</body></html>\n")
    path = out / "report.html"
    write_text_atomic(path, "\n".join(parts))
    return path


def _files(out: Path, s: Section, globs) -> list[Path]:
    base = out / s.folder
    found = []
    for g in globs:
        found += sorted(p for p in base.glob(g) if p.is_file() and p.name != "report.html")
    return found


def _present(out: Path, s: Section) -> bool:
    return bool(_files(out, s, s.tables + s.figures + s.raw))


def _section_html(out: Path, s: Section, k: int) -> str:
    h = [f"<section id='s{k}'><h2>{html.escape(s.title)}</h2>",
         f"<p class=cmd>Command: <code>{html.escape(s.command)}</code></p>"]
    if not _present(out, s):
        h.append("<p class=missing>Not run: no results under "
                 f"<code>{html.escape(str(out / s.folder))}</code>. Run the command above.</p></section>")
        return "\n".join(h)
    if s.seed:
        h.append(f"<div class=seed><b>The seed reports:</b> {markdown_to_html(s.seed)}</div>")
    for p in _files(out, s, s.tables):
        h.append(f"<div class=table><p class=file>{html.escape(p.name)}</p>{markdown_to_html(p.read_text())}</div>")
    if s.notes:
        h.append(markdown_to_html(s.notes))
    for p in _files(out, s, s.figures):
        rel = p.relative_to(out).as_posix()
        h.append(f"<figure><a href='{html.escape(rel)}'><img src='{html.escape(rel)}' alt='{html.escape(p.name)}'></a>"
                 f"<figcaption>{html.escape(rel)}</figcaption></figure>")
    links = [(p, "recording") for p in _files(out, s, s.recordings)] + [(p, "data") for p in _files(out, s, s.raw)]
    if links:
        h.append("<p class=links>" + " &middot; ".join(
            f"<a href='{html.escape(p.relative_to(out).as_posix())}'>{html.escape(p.name)}</a> ({kind})"
            for p, kind in links) + "</p>")
    h.append("</section>")
    return "\n".join(h)


def markdown_to_html(text: str) -> str:
    """Headings, paragraphs, bullet lists, pipe tables, fenced code and inline code/bold."""
    lines = text.splitlines()
    out, i = [], 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("```"):
            j = i + 1
            while j < len(lines) and not lines[j].startswith("```"):
                j += 1
            out.append("<pre>" + html.escape("\n".join(lines[i + 1:j])) + "</pre>")
            i = j + 1
        elif line.startswith("|"):
            j = i
            while j < len(lines) and lines[j].startswith("|"):
                j += 1
            out.append(_table(lines[i:j]))
            i = j
        elif m := re.match(r"(#{1,6})\s+(.*)", line):
            level = min(len(m.group(1)) + 2, 6)
            out.append(f"<h{level}>{_inline(m.group(2))}</h{level}>")
            i += 1
        elif re.match(r"\s*[-*]\s+", line):
            items = []
            while i < len(lines) and re.match(r"\s*[-*]\s+", lines[i]):
                item = re.sub(r"^\s*[-*]\s+", "", lines[i])
                items.append(f"<li>{_inline(item)}</li>")
                i += 1
            out.append("<ul>" + "".join(items) + "</ul>")
        elif not line.strip():
            i += 1
        else:
            j = i
            while j < len(lines) and lines[j].strip() and not re.match(r"(\||#|```|\s*[-*]\s)", lines[j]):
                j += 1
            out.append(f"<p>{_inline(' '.join(lines[i:j]))}</p>")
            i = j
    return "\n".join(out)


def _table(rows: list[str]) -> str:
    cells = [table_cells(r) for r in rows]
    body = [r for r in cells if not all(re.fullmatch(r":?-{3,}:?", c) for c in r)]
    if not body:
        return ""
    head, rest = body[0], body[1:]
    bad = [k + 1 for k, r in enumerate(rest) if len(r) != len(head)]
    warn = (f"<p class=missing>This table is misaligned: rows {bad} do not have the header's {len(head)} cells "
            "(a literal bar in a cell must be written \\|).</p>" if bad else "")
    return warn + ("<table><thead><tr>" + "".join(f"<th>{_inline(c)}</th>" for c in head) + "</tr></thead><tbody>"
            + "".join("<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in r) + "</tr>" for r in rest)
            + "</tbody></table>")


def table_cells(row: str) -> list[str]:
    """The cells of one Markdown pipe-table row; a literal bar is written `\\|` inside a cell."""
    inner = row.strip()
    inner = inner[1:] if inner.startswith("|") else inner
    inner = inner[:-1] if inner.endswith("|") and not inner.endswith("\\|") else inner
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", inner)]


def _inline(text: str) -> str:
    t = html.escape(text)
    t = re.sub(r"`([^`]+)`", r"<code>\1</code>", t)
    return re.sub(r"\*\*([^*]+)\*\*", r"<b>\1</b>", t)


_HEAD = """<!doctype html><html><head><meta charset='utf-8'><title>qmt_drake report</title><style>
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.6em} h2{border-bottom:2px solid #ccd;padding-bottom:.2em;margin-top:2em}
table{border-collapse:collapse;font-size:.85em;margin:.6em 0} td,th{border:1px solid #bbc;padding:.2em .5em}
th{background:#eef} code{background:#f3f3f6;padding:0 .2em} .cmd{color:#444} .missing{color:#a33}
.seed{background:#fff8e6;border-left:4px solid #e5b000;padding:.4em .8em} .file{color:#666;font-size:.8em;margin:0}
figure{display:block;margin:.8em 0} img{max-width:100%;border:1px solid #ddd}
figcaption{font-size:.75em;color:#666} .meta{color:#666;font-size:.9em}
</style></head><body>"""
