# Two commands do everything on a fresh machine with Python 3.11 and make:
#   make demo   - create .venv, install ceamcl, run the demo, write demo-out/
#   make test   - same set-up, then ruff, mypy and the test suite
PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

# ROS 2 (tests/ros, examples): DDS discovery stays on this machine (docs/ros.md).
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST

.PHONY: demo test lint typecheck pytest bench clean

# The ROS 2 extras come from PyPI; tf2_msgs, which is not there, is built into the venv from its
# .msg (cmake + gcc, a few seconds; docs/ros.md).
$(STAMP): pyproject.toml ros/build-tf2-msgs.sh ros/tf2_msgs/CMakeLists.txt ros/tf2_msgs/package.xml ros/tf2_msgs/msg/TFMessage.msg
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,peers,distributed,ros,ros-build]'
	sh ros/build-tf2-msgs.sh $(VENV)
	@touch $(STAMP)

demo: $(STAMP)
	$(BIN)/ceamcl demo --out demo-out

lint: $(STAMP)
	$(BIN)/ruff check src tests

typecheck: $(STAMP)
	$(BIN)/mypy

# Two workers (pytest-xdist), one per core of the project's machines; --dist loadscope keeps
# each module's tests on one worker, so a module's shared fixture (the fingerprint runs) is
# computed once. PYTEST_WORKERS=0 runs the suite in this process.
PYTEST_WORKERS ?= 2
pytest: $(STAMP)
	$(BIN)/python -m pytest -q -n $(PYTEST_WORKERS) --dist loadscope

test: lint typecheck pytest

# Regression benchmarks of the hot kernels (pytest-benchmark), then the full `ceamcl bench`.
bench: $(STAMP)
	$(BIN)/python -m pytest -q benchmarks --benchmark-enable
	$(BIN)/ceamcl bench --out bench-out

clean:
	rm -rf $(VENV) demo-out .mypy_cache .ruff_cache .pytest_cache
