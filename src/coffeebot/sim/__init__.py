"""The simulated world and the simulated devices that speak the real protocols to it."""
