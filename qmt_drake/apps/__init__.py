"""What users run: the `qmt-drake` command line (cli.py), the studies' shared helpers
(thesis_study.py, plots.py), the benchmark (benchmark.py), the planner speed bench (bench.py)
and the report of everything (report.py)."""
