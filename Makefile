# Two commands on a fresh machine: `make demo` (install + run the main job) and `make test`.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
OUT ?= out

.PHONY: install demo test bench clean

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

clean:
	rm -rf $(VENV) $(OUT) *.egg-info
