"""Drake systems of the transfer co-simulation, one concept per module; each LeafSystem has named
ports and documents them with their units.

    dc_motor.DcMotorWithGear          voltage command -> joint torque (armature, back EMF, gear, limits)
    joint_tracking.JointPidController reference + measured state -> voltage command (PID, anti-windup)
    electromagnet.ElectromagnetForce  coil current + body poses -> pull on the payload, reaction on hand
    transfer_monitor.TransferMonitor  slip, tilt, detachment, tracking error, motor peaks, energy
    payload.add_payload               the carried part as a free body in friction contact (not a system)

qmt_drake.sim wires them into one diagram; the tests compose them by hand as user code would.
"""
