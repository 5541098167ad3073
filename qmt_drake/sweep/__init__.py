"""Sweeps of co-simulated transfers on Dask: specs (spec.py), cases and their worker function
(cases.py), the keyed result store (store.py), the runner (runner.py) and its Dask cluster
(cluster.py), success statistics (stats.py), robust and carried planners (robust.py) and the
`qmt-drake sweep` command (cli.py)."""
