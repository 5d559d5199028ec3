# Two commands on a fresh machine: `make demo` (install + run the main job) and `make test`.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
OUT ?= out

DOCS_OUT ?= docs/_build/html

.PHONY: install demo test bench docs claims clean csrc-lint

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

# The notebooks the suite executes are kept for the documentation site (docs/conf.py renders them as they ran).
NOTEBOOK_OUTPUTS ?= docs/_build/executed_notebooks

test: install
	rm -rf $(NOTEBOOK_OUTPUTS)
	CARTPOLE_NOTEBOOK_OUTPUTS=$(abspath $(NOTEBOOK_OUTPUTS)) MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/python -m pytest -q -n 2 --durations=30

bench: install
	$(BIN)/cartpole bench

# Each C file of cartpole/csrc compiled alone with the export's strict flags against sample configurations the
# exporter renders (build/csrc-sample/<design>/{include,src}; tools/csrc_sample.py prints every command).
csrc-lint: install
	$(BIN)/python tools/csrc_sample.py build/csrc-sample

# The documentation site, warnings as errors (the API reference imports the package: headless GL as for the tests),
# then checked as a reader sees it (tests/docs/test_site.py). The notebook pages show the outputs `make test` kept;
# a notebook without them is executed here (short runs, cached in docs/_build/.jupyter_cache).
docs: install
	rm -rf docs/api/generated
	CARTPOLE_NOTEBOOK_OUTPUTS=$(abspath $(NOTEBOOK_OUTPUTS)) MUJOCO_GL=$${MUJOCO_GL:-egl} \
	  $(BIN)/sphinx-build -W --keep-going -q -b html docs $(DOCS_OUT)
	CARTPOLE_SITE=$(abspath $(DOCS_OUT)) MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/python -m pytest -q tests/docs/test_site.py
	@echo "The site is at $(DOCS_OUT)/index.html"

# Every number the README and the docs state, re-measured by its command (claims.toml); `CLAIMS_ARGS=--quick` for
# the quick set, `CLAIMS_ARGS="--id ID"` for one. Exit 1 names each claim that moved. Each measured claim is appended to
# claims-ledger.jsonl (commit, CPU, date): `CLAIMS_ARGS="--pending-since YYYY-MM-DD"` resumes a campaign begun that day.
# The crocoddyl extra too: `cartpole bench`'s side-by-side claims (bench.crocoddyl_*) measure Crocoddyl's FDDP.
claims: install
	$(BIN)/pip install --quiet -e ".[dev,crocoddyl]"
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/python tools/claims.py --ledger claims-ledger.jsonl $(CLAIMS_ARGS)

clean:
	rm -rf $(VENV) $(OUT) *.egg-info docs/_build docs/api/generated docs/notebooks
