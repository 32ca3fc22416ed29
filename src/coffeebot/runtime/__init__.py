"""The daemon put together: which modules run and how they are wired (``assemble``), the web
UI's wiring (``web``), the robot's buses (``robot``), running as a service (``service``) and
the simulated robot (``sim``). Only ``sim`` imports the simulator, so the robot never loads it.
"""
