"""Device drivers. Each takes an already-open bus or port object and never opens a device
itself, so the same driver runs against smbus2/pyserial on the robot and against the
simulated devices in :mod:`coffeebot.sim` in tests."""
