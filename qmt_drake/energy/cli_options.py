"""The energy-time options of `qmt-drake plan`, apart from energy/cli.py (which runs them) so that the
command line's parser, and `qmt-drake plan --help`, load no Drake."""

from __future__ import annotations

import argparse


def add_energy_options(p: argparse.ArgumentParser) -> None:
    """The options of `plan` that only energy-time scenarios take (--method snopt|steepest|ipopt|collocation)."""
    g = p.add_argument_group("energy-time scenarios (seed 001: --method snopt, steepest, ipopt, collocation)")
    g.add_argument("--c1", type=float, default=None, help="weight of tau'tau (default: the experiment's)")
    g.add_argument("--c2", type=float, default=None, help="weight of time, > 0 (default: the experiment's)")
    g.add_argument("--m", type=int, default=None, help="Fourier terms per joint, >= 1 (default 5)")
    g.add_argument("--divisions", type=int, default=None, help="time divisions of the integral (default 40)")
    g.add_argument("--coords", type=float, nargs=4, default=None, metavar="X",
                   help="coordinate vector X1(0) X2(0) X1(T) X2(T) in m (X2 up)")
    g.add_argument("--pattern", default=None,
                   help='rotation-direction start: "--pattern=-+-" or "npn" (p = +, n = -), or "all" (default)')
    g.add_argument("--max-iter", type=int, default=None, help="steepest: iteration cap (default 20000)")
    g.add_argument("--execute", default=None, metavar="PNG",
                   help="run the best optimum in the Drake co-simulation and plot tracking to PNG")
    g.add_argument("--recording", default=None, metavar="HTML", help="Meshcat recording of that execution")
