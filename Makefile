# Entry points for a fresh machine: `make demo`, `make test` and `make lint` (what CI runs before the tests).
# Each creates its own virtual environment in .venv and installs the package into it.
PY ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint install clean

$(STAMP): pyproject.toml requirements-vot.txt
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	# torch is pinned to its CPU build: an unpinned torch pulls a CUDA build of several GB.
	$(BIN)/pip install -q "torch==2.13.0" "numpy<2"
	$(BIN)/pip install -q -e ".[test]"
	# --no-deps: see requirements-vot.txt (its dependencies would replace cv2's contrib build)
	$(BIN)/pip install -q --no-deps -r requirements-vot.txt
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	mkdir -p out
	$(BIN)/dvsot generate blender_scenes/quickstart.yaml -o out/quickstart.h5 --preview
	$(BIN)/dvsot info out/quickstart.h5

test: $(STAMP)
	# loadfile: each test file runs on one worker, so its module-scoped fixtures (trained networks) run once.
	$(BIN)/python -m pytest -n auto --dist loadfile

# ruff (the test extras' pin) with pyproject.toml's [tool.ruff]: style, import order, pyflakes; seconds
lint: $(STAMP)
	$(BIN)/ruff check .

clean:
	rm -rf $(VENV) out
