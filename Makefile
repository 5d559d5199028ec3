# Two commands on a fresh machine: `make demo` (install + run the main job) and `make test`.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
OUT ?= out

DOCS_OUT ?= docs/_build/html

.PHONY: install demo test bench docs claims clean

$(BIN)/activate:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip

install: $(BIN)/activate
	$(BIN)/pip install --quiet -e ".[dev]"

demo: install
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/cartpole linearize
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/cartpole lqr --compare-pid --out $(OUT)
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/cartpole lqr --mjcf cartpole/assets/cartpole_two_pole.xml --out $(OUT)/two_pole
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/cartpole swingup --method energy --out $(OUT)
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/cartpole swingup --method trajopt --out $(OUT)
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/cartpole feedforward --out $(OUT)
	@echo "Figures, videos and metrics are under $(OUT)/"

test: install
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/python -m pytest -q -n 2

bench: install
	$(BIN)/cartpole bench

# The documentation site, warnings as errors (the API reference imports the package: headless GL as for the tests).
docs: install
	rm -rf docs/api/generated
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/sphinx-build -W --keep-going -q -b html docs $(DOCS_OUT)
	@echo "The site is at $(DOCS_OUT)/index.html"

# Every number the README and the docs state, re-measured by its command (claims.toml); `CLAIMS_ARGS=--quick` for
# the quick set, `CLAIMS_ARGS="--id ID"` for one. Exit 1 names each claim that moved.
claims: install
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/python tools/claims.py $(CLAIMS_ARGS)

clean:
	rm -rf $(VENV) $(OUT) *.egg-info docs/_build docs/api/generated docs/notebooks
