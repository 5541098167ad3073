"""Task-oriented structural design of 6-DOF arms by operability (seed 003, Kotosaka et al. 1995).

Modules: arm_types (joint-combination types, kinematics, URDF, Drake plant), operability (eq. 2-8),
ik (every inverse-kinematics branch, collision with the work and obstacles), tasks (task YAML),
problem (the link-length design problem), search (GA adapter, exhaustive certificate), cli, plots.
See README.md in this folder for the reconstruction of the seed's definitions.
"""
