# Quickstart:  make demo   |   make test   |   make docs (the site, into site/)
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.drltg-installed

.PHONY: demo test docs install clean

# (Re)install only when the dependency pins change; a second run starts in seconds.
$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[robosuite,test,docs]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/drltg demo

# One worker per core; a file's tests share a worker, so its module fixtures are built once. OpenBLAS's
# kernel is pinned so that NumPy's and numba's builds round alike on every CPU and the robosuite tests run the
# lean step (drltg falls back to robosuite's own step where they differ, docs/tasks.md).
test: $(STAMP)
	OPENBLAS_CORETYPE=Haswell $(BIN)/python -m pytest -n auto --dist loadfile

docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

clean:
	rm -rf $(VENV) site
