#!/bin/bash
# Issue 15 (helper radproj): a warm cache for projection_cpu_run1.sh, as projection_cpu_warm.sh plus one compiled
# Radau simulate of the warm-up copy (so that the Radau entry point a kept-constraint run uses is compiled in both
# trees, while no measured system's own functions are). usage: radproj_cpu_warm.sh SRC WARMDIR
SRC=$1; W=$2
bash "$(dirname "$0")/projection_cpu_warm.sh" "$SRC" "$W"
cd "$SRC" || exit 2
export LAGRANGE_CACHE_DIR=$W PYTHONPATH=$SRC
COPY=$(mktemp -d "${TMPDIR:-/tmp}/radprojwarm.XXXX")
sed 's/^title: .*/title: Warm-up pendulum kept with a multiplier (benchmark cache only)/' systems/pendulum_multiplier.yaml > "$COPY/warm_pendulum.yaml"
/work/main/.venv/bin/python -m lagrange_cli simulate "$COPY/warm_pendulum.yaml" --method Radau --backend compiled -q -o "$COPY/out.npz" > /dev/null || echo WARM STEP FAILED
rm -rf "$COPY"
