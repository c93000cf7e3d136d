# Two entry points: `make demo` and `make test`. Both build .venv when missing.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# mediapipe's declared pins would downgrade numpy and pull GUI OpenCV and jax;
# its real runtime dependencies come from the project's `pose` extra instead.
MEDIAPIPE := mediapipe==0.10.21
export NUMBA_CACHE_DIR := $(CURDIR)/$(VENV)/numba-cache

.PHONY: demo test lint install clean browser

install: $(STAMP) browser

# The web page's tests drive Debian's chromium through Playwright, which never downloads a browser.
browser:
	command -v chromium >/dev/null || (apt-get update && apt-get install -y chromium)

$(STAMP): pyproject.toml constraints.txt
	$(PY) -m pip --version >/dev/null 2>&1 || $(PYTHON) -m venv --clear $(VENV)
	$(PY) -m pip install --upgrade pip
	$(PY) -m pip install -c constraints.txt -e ".[pose,test]"
	$(PY) -m pip install --no-deps $(MEDIAPIPE)
	touch $@

demo: $(STAMP)
	$(VENV)/bin/dancesynth demo --out demo_output

lint: $(STAMP)
	$(VENV)/bin/ruff check .

# One single-threaded test process per core: the suite's tests are independent and mostly single-threaded.
test: lint browser
	OMP_NUM_THREADS=1 $(PY) -m pytest -q -n auto

clean:
	rm -rf $(VENV) demo_output
