"""Per-step trace of a held DC law: why a held voltage lost the UR5 suction box (docs/spatial_drives.md, session 17).

    PYTHONPATH=$PWD .venv/bin/python -m studies.held_trace ur5-suction-bins --period-ms 4 --amplifier voltage \
        --scale 1.05 --until 0.08 [--from 0.04] [--feedforward shaped]

Builds the co-simulation of the TOPP-RA plan (api.plan_with) on the DC-motor drive with the law held at the period
behind the amplifier, advances it to --until without the hold check (the part stays welded, so the trace runs on past
the first ratio above 1) and prints every plant step from --from: the hand's ratio (weld hand: the hand term's largest
column of the part's logged motion; tray: the cup contact's ratio), the tracking error q_des - q [mrad], the motors'
torque N k_t i [N m] and the joint speeds [rad/s]. Nothing is written.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from pydrake.systems.analysis import Simulator

from qmt_drake.api import load_scenario, plan_with
from qmt_drake.limits.tray_contact import TrayContactTerm
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.spatial_actuation import HELD_AMPLIFIERS, SpatialMotorDrive
from qmt_drake.sim.spatial_cosim import build_spatial_cosim
from qmt_drake.sim.spatial_tray_hand import SETTLE_S


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("--period-ms", type=float, default=4.0)
    ap.add_argument("--amplifier", default=HELD_AMPLIFIERS[0], choices=HELD_AMPLIFIERS)
    ap.add_argument("--feedforward", default="shaped", choices=["shaped", "full"])
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--until", type=float, default=0.08)
    ap.add_argument("--from", dest="start", type=float, default=0.0)
    a = ap.parse_args(argv)
    sc = load_scenario(a.scenario)
    traj = plan_with("toppra", sc).trajectory
    traj = traj if a.scale == 1.0 else TimeScaled(traj, a.scale)
    drive = SpatialMotorDrive.for_scenario(sc, traj.sample([0.0])[0][0], a.feedforward,
                                           control_period_s=a.period_ms * 1e-3, amplifier=a.amplifier)
    cs = build_spatial_cosim(sc, traj, actuator="dc_motor", feedforward=a.feedforward, drive=drive)
    sim = Simulator(cs.diagram)
    cs.simulator = sim
    cs.start(sim)
    sim.AdvanceTo(a.until)
    ctx = sim.get_context()
    q, d, i = (cs.loggers[k].FindLog(ctx) for k in ("arm_state", "desired_state", "current"))
    t, n = q.sample_times(), sc.n_dof
    if cs.kind == "spatial_tray":
        tr, r = cs.monitor.ratios(ctx, TrayContactTerm(sc.cup, sc.gravity_m_s2), SETTLE_S)
    else:
        tr, r = cs.monitor.ratios(ctx, 1, None)
    tau = (drive.params.gear_ratio * drive.params.torque_constant_Nm_per_A)[:, None] * i.data()
    np.set_printoptions(linewidth=250, precision=3, suppress=True)
    print("t [ms] | hand ratio | q_des - q [mrad] | motor torque N k_t i [N m] | qd [rad/s]")
    for k in np.flatnonzero(t >= a.start - 1e-12):
        j = np.searchsorted(tr, t[k] - 1e-12)
        ratio = r[j] if j < len(r) and abs(tr[j] - t[k]) < 1e-9 else np.nan
        print(f"{t[k] * 1e3:6.0f} {ratio:7.3f}  {(d.data()[:n, k] - q.data()[:n, k]) * 1e3}  {tau[:, k]}  "
              f"{q.data()[n:, k]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
