"""Seed 001 (Ohsaka & Kurahashi 1988): energy-time optimal trajectories of a vertical arm with
Fourier joint velocities. See README.md in this folder."""
