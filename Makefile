# Two commands do all the set-up on a fresh machine with Python 3.11:
#   make demo   # closed-loop demo (planner + plant over ROS 2), summary + plot
#   make test   # the whole test suite and the linter (what CI runs: .ci/run)
# Both create .venv on first use and install the package with ROS 2 Jazzy
# from PyPI (the 'ros' extra), test tools, benchmark peers and numba (the 'fast' extra).

PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test bench plan lint clean

$(STAMP): setup.py package.xml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[ros,test,bench,fast]'
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/flexmotion demo --config config/wie_bernstein.yaml --goal 1.0 --plot demo.png

test: $(STAMP)
	$(PY) -m pytest -q
	$(PY) -m ruff check .
	$(PY) -m ruff format --check .

bench: $(STAMP)
	$(PY) bench/planner_latency.py

lint: $(STAMP)
	$(PY) -m ruff check .
	$(PY) -m ruff format --check .

clean:
	rm -rf $(VENV) build install log .pytest_cache
