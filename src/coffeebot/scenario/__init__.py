"""Scenarios: a reproducible run of the whole daemon on the simulated world, and its report.

``spec`` reads the scenario file, ``driver`` plays it inside the daemon, ``report`` is what
comes out, ``run`` puts the three together (:func:`~coffeebot.scenario.run.run_scenario`).
"""
