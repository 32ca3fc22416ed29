"""Simulated devices that speak the real protocols, plugged in where a bus or port would be."""
