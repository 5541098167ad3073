"""Configuration: the typed scenario (scenario.py) every other package reads."""
