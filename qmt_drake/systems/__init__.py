"""Drake systems of the transfer co-simulation, one concept per module; each system has named
ports and documents them with their units. Laws that run every plant step are written once (floats
and drake symbolic, scalar_ops) and compiled into Drake primitives: no Python per step.

    dc_motor.DcMotorWithGear          voltage command -> joint torque (armature, back EMF, gear, limits);
    dc_motor.dc_motors_as_primitives  the same (quasi-static armature) as Drake primitives, what sim uses
    joint_tracking.JointPidController reference + measured state -> voltage command (PID, anti-windup)
    electromagnet.electromagnet_force coil current + plant state -> pull on the payload's joint (primitives)
    transfer_monitor.TransferMonitor  slip, tilt, detachment, tracking error, motor peaks, energy (per step)
    transfer_monitor.payload_motion_as_primitives   slip, tilt, gap from the payload's joint (primitives)
    payload.add_payload               the carried part on its 6-DOF joint to the hand, in friction contact
                                      with the face (not a system)

qmt_drake.sim wires them into one diagram; the tests compose them by hand as user code would.
"""
