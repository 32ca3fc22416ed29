# The two commands a newcomer needs: `make run` and `make test`. Each sets itself up from nothing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run fleet-demo test lint screenshots system-deps clean install

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	touch $(STAMP)

# The demo: the whole daemon on the simulated robot, web UI on http://127.0.0.1:8080;
# `make run HOST=0.0.0.0` opens it to other machines (a phone on the same network).
HOST ?= 127.0.0.1
PORT ?= 8080
run: $(STAMP)
	$(BIN)/coffeebot sim --host $(HOST) --port $(PORT)

# The fleet demo: a Mosquitto broker of its own, the dispatcher (web UI on the same address)
# and ROBOTS simulated robots in one building (docs/fleet.md).
ROBOTS ?= 3
fleet-demo: $(STAMP) system-deps
	$(BIN)/coffeebot fleet --sim $(ROBOTS) --host $(HOST) --port $(PORT)

# On the robot, as root, in a checkout at /opt/coffeebot: the systemd unit, its user and a
# default /etc/coffeebot (docs/robot.md).
install: $(STAMP)
	$(BIN)/coffeebot install-service

system-deps:
	./.ci/system-deps

test: $(STAMP) system-deps
	$(BIN)/ruff check src tests bench
	$(BIN)/mypy
	$(BIN)/python -m pytest -n auto --dist loadgroup

# Refresh the README's screenshots from the browser tests.
screenshots: $(STAMP) system-deps
	COFFEEBOT_SCREENSHOTS=docs/screenshots $(BIN)/python -m pytest -q tests/web/test_browser_sim.py tests/web/test_browser_camera_cart.py tests/fleet/test_fleet_map.py

lint: $(STAMP)
	$(BIN)/ruff check src tests bench
	$(BIN)/mypy

clean:
	rm -rf $(VENV) build src/*.egg-info .pytest_cache .ruff_cache
