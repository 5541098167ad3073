"""Seed 002: carrying an unfixed bottle on a tray with a CRANE-X7 arm (IK, waypoints, tray limits,
co-simulation)."""
