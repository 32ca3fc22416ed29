"""Perception algorithms: pure, clock-free classes the board modules wrap."""
