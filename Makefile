# Every target sets up what it needs: a virtual environment in .venv (and pdflatex for tests).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench fuzz golden latex-deps toolchains animate-deps clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --disable-pip-version-check -e '.[dev]'
	touch $@

demo: $(STAMP)
	$(BIN)/lagrange derive double_pendulum

test: $(STAMP) latex-deps toolchains animate-deps
	$(BIN)/python -m pytest -q -n auto --dist worksteal  # one worker per core (pytest-xdist)

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy lagrange_cli

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py  # issue 14: the general chain, whole processes against sympy.physics.mechanics, N up to 60
	$(BIN)/python benchmarks/spatial_bench.py  # issue 13: the spatial chain N = 2..6, whole processes (CPU time) against KanesMethod / LagrangesMethod at N = 2..4
	$(BIN)/python benchmarks/simulate_bench.py --write
	$(BIN)/python benchmarks/c_bench.py --write  # issue 16: generated C per call against hand-written C and the pure-Python module
	$(BIN)/python benchmarks/study_bench.py
	$(BIN)/python benchmarks/every_system.py --write  # about an hour: accuracy and stress on every file in systems/

# Hostile system files by the ten thousand (tests/fuzzing.py's cases); results go to FUZZ.md.
# FUZZ_COUNT=100000 for the full run (about 20 minutes on two quiet cores).
FUZZ_COUNT ?= 20000
fuzz: $(STAMP)
	$(BIN)/python benchmarks/fuzz.py --count $(FUZZ_COUNT) --workers 2 --write

golden: $(STAMP)
	$(BIN)/python -m pytest -q tests/test_golden.py --update-golden

# pdflatex (Debian's texlive-latex-base) for the tests that compile LaTeX output.
latex-deps:
	@command -v pdflatex >/dev/null 2>&1 || { \
	  sudo=$$([ "$$(id -u)" = 0 ] || echo sudo); \
	  $$sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$sudo apt-get install -y -qq texlive-latex-base >/dev/null; }

# The compilers and interpreters the code targets are tested in (tests/test_target_c.py, tests/test_target_octave.py):
# gcc and g++ for `derive --to c`, Octave for `derive --to octave` (large: without its recommends).
toolchains:
	@command -v gcc >/dev/null 2>&1 && command -v g++ >/dev/null 2>&1 || { \
	  sudo=$$([ "$$(id -u)" = 0 ] || echo sudo); \
	  $$sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$sudo apt-get install -y -qq gcc g++ libc6-dev >/dev/null; }
	@command -v octave >/dev/null 2>&1 || { \
	  sudo=$$([ "$$(id -u)" = 0 ] || echo sudo); \
	  $$sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$sudo apt-get install -y -qq --no-install-recommends octave >/dev/null; }

# ffmpeg (MP4 animations) and chromium (the test that plays an HTML animation headless), from Debian.
animate-deps:
	@command -v ffmpeg >/dev/null 2>&1 && command -v chromium >/dev/null 2>&1 || { \
	  sudo=$$([ "$$(id -u)" = 0 ] || echo sudo); \
	  $$sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$sudo apt-get install -y -qq ffmpeg chromium >/dev/null; }

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache
