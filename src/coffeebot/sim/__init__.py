"""The simulated robot and building: the world model and the simulated devices around it."""
