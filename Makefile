# Set-up and the two jobs a new user runs (see README.md). Python 3.11, Debian, no GPU needed.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
OUT ?= runs/demo

.PHONY: demo test lint install install-test install-ros ros-demo clean

$(VENV)/bin/activate:
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

# An editable install leaves foldbot's own modules uncompiled, and where PYTHONDONTWRITEBYTECODE is
# set (as on this workplace's machines) every process, each ROS node among them, compiled them
# again: 0.22 s of the 1.15 s a fold's process took to start. Compiled once here, they are read
# from __pycache__ (a file edited since is compiled again in memory, as usual).
COMPILE := $(PY) -m compileall -q src ros

install: $(VENV)/bin/activate
	$(PY) -m pip install --quiet -c constraints.txt -e .
	$(COMPILE)

install-test: $(VENV)/bin/activate
	$(PY) -m pip install --quiet -c constraints.txt -e ".[test]"
	$(COMPILE)

## demo: install, then fold a 30 cm towel headless and write the episode folder to $(OUT)
demo: install
	$(VENV)/bin/foldbot fold --garment towel --perception vision --out $(OUT) --overwrite

## install-ros: ROS 1 from Debian (apt-get, needs root or sudo), importable from the venv
install-ros: $(VENV)/bin/activate
	bash scripts/install_ros.sh $(VENV)

## ros-demo: the same fold over ROS 1 topics (roslaunch), recorded to $(OUT)-ros.bag
ros-demo: install install-ros
	$(VENV)/bin/foldbot ros-fold --garment towel --out $(OUT)-ros --record $(OUT)-ros.bag --overwrite

## test: install the test dependencies and ROS 1, lint, and run the whole suite (one pytest
## worker per core; a module's tests stay on one worker, in order; the 20 slowest named at the end)
test: install-test install-ros
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(PY) -m pytest -q -n auto --dist loadscope --durations=20

lint: install-test
	$(VENV)/bin/ruff check . && $(VENV)/bin/ruff format --check .

clean:
	rm -rf $(VENV) runs .pytest_cache .ruff_cache src/*.egg-info
	find src ros tests -name __pycache__ -prune -exec rm -rf {} +
