#!/bin/bash
# Issue 15 (helper projkern): a warm cache for projection_cpu_run1.sh. usage: projection_cpu_warm.sh SRC WARMDIR
# stress + accuracy of systems/double_pendulum.yaml, and one compiled simulate of systems/pendulum_multiplier.yaml
# under another title (its own generated module): the kernels' entry points compiled, no measured system's functions.
SRC=$1; W=$2; rm -rf "$W"; mkdir -p "$W"; cd "$SRC" || exit 2
export LAGRANGE_CACHE_DIR=$W PYTHONPATH=$SRC
COPY=$(mktemp -d "${TMPDIR:-/tmp}/projwarm.XXXX")
sed 's/^title: .*/title: Warm-up pendulum kept with a multiplier (benchmark cache only)/' systems/pendulum_multiplier.yaml > "$COPY/warm_pendulum.yaml"
/work/main/.venv/bin/python -m lagrange_cli stress systems/double_pendulum.yaml -q --json /dev/null > /dev/null || echo WARM STEP FAILED
/work/main/.venv/bin/python -m lagrange_cli accuracy systems/double_pendulum.yaml -q --json /dev/null > /dev/null || echo WARM STEP FAILED
/work/main/.venv/bin/python -m lagrange_cli simulate "$COPY/warm_pendulum.yaml" --method DOP853 --backend compiled -q -o "$COPY/out.npz" > /dev/null || echo WARM STEP FAILED
rm -rf "$COPY"
