# Two commands set everything up on a fresh machine: `make demo` and `make test`.
# Each creates the virtual environment in .venv when it is missing.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin

.PHONY: venv demo test test-cpus lint bench clean

$(BIN)/depthgram: pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[dev]'
	touch $(BIN)/depthgram

venv: $(BIN)/depthgram

demo: venv
	$(BIN)/depthgram demo --out demo-out

test: venv
	$(BIN)/python -m pytest

# OpenBLAS picks its kernels by CPU, and the last bits of numpy's linear algebra move with them:
# the tests that reach it (segmentation, golden cases, sensor model, dynamics) again under the
# kernels of other common CPUs, which this machine takes when told to
NUMERIC_TESTS := tests/test_segment*.py tests/test_golden.py tests/test_dynamics*.py tests/test_sensor*.py \
	tests/test_label_oracles.py tests/test_window_sums.py tests/test_ransac_order.py tests/test_pipeline.py
test-cpus: venv
	for core in Zen Haswell SkylakeX; do \
		echo "OPENBLAS_CORETYPE=$$core"; \
		OPENBLAS_CORETYPE=$$core $(BIN)/python -m pytest -p no:cacheprovider $(NUMERIC_TESTS) || exit 1; \
	done

lint: venv
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/ruff format --check src tests benchmarks
	$(BIN)/mypy src

bench: venv
	$(BIN)/depthgram bench

clean:
	rm -rf $(VENV) demo-out .pytest_cache .mypy_cache
