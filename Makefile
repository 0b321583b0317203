# Two-command set-up: `make demo` and `make test` each create .venv and install everything.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
export OMP_NUM_THREADS ?= 1
export NO_MKDOCS_2_WARNING ?= 1

.PHONY: install demo readme-gif test lint docs docs-serve bench clean

$(VENV)/.installed: pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	# torch first, so that stable-baselines3 keeps it. On this project's machines the pin
	# resolves to a CPU wheel; elsewhere pass TORCH_INDEX=https://download.pytorch.org/whl/cpu
	# (PyPI's torch==2.13.0 for Linux is the multi-GB CUDA build).
	$(PY) -m pip install -q torch==2.13.0 $(if $(TORCH_INDEX),--index-url $(TORCH_INDEX))
	$(PY) -m pip install -q -e ".[dev,rl,ray,ompl,docs]"
	touch $@

install: $(VENV)/.installed

# One expert episode; the GIF goes to runs/ (ignored by git), so the clone stays clean. The
# planners stop on iteration caps, not the clock: a budget far above their need makes the
# episode the same on a slow or busy machine.
demo: $(VENV)/.installed
	mkdir -p runs
	$(VENV)/bin/slide-gym run --object E --table square --seed 0 --time-budget 60 \
		--video runs/demo.gif --json

# The README's GIF: the same episode, rewritten in place; commit it with the code it shows.
readme-gif: $(VENV)/.installed
	$(VENV)/bin/slide-gym run --object E --table square --seed 0 --time-budget 60 \
		--video docs/expert.gif --json

test: lint docs
	$(PY) -m pytest -q

lint: $(VENV)/.installed
	$(PY) -m ruff check .
	$(PY) -m ruff format --check .

# The documentation site (mkdocs.yml, docs/): strict, so a broken link, anchor, missing page
# or docstring reference fails.
docs: $(VENV)/.installed
	$(PY) -m mkdocs build --strict  # not --quiet: it hides the warnings that strict counts

docs-serve: $(VENV)/.installed
	$(PY) -m mkdocs serve

bench: $(VENV)/.installed
	$(VENV)/bin/slide-gym bench env

clean:
	rm -rf $(VENV) build dist site *.egg-info .pytest_cache .ruff_cache
