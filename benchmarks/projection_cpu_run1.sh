#!/bin/bash
# Issue 15 (helper projkern): CPU of one `lagrange CMD FILE -q --json` from a copy of a warm cache (BENCHMARKS.md,
# "projection inside the compiled loop"). usage: projection_cpu_run1.sh SRC OUTDIR WARMDIR CMD FILE (FILE relative to SRC)
SRC=$1; OUT=$2; WARM=$3; CMD=$4; F=$5
mkdir -p "$OUT"
name=$(echo "$F" | sed 's#^tests/##; s#/#__#g; s#\.yaml$##')
C=$(mktemp -d "${TMPDIR:-/tmp}/projcache.XXXX")
cp -r "$WARM"/. "$C"/
cd "$SRC" || exit 2
LAGRANGE_CACHE_DIR=$C PYTHONPATH=$SRC /usr/bin/time -f "%U %S %e" -o "$OUT/$name.$CMD.time" /work/main/.venv/bin/python -m lagrange_cli "$CMD" "$F" -q --json "$OUT/$name.$CMD.json" > "$OUT/$name.$CMD.out" 2> "$OUT/$name.$CMD.err"
echo $? > "$OUT/$name.$CMD.rc"
rm -rf "$C"
echo "$(date -u +%H:%M:%S) load $(cut -d' ' -f1-3 /proc/loadavg) $name $CMD $(tail -1 "$OUT/$name.$CMD.time") rc=$(cat "$OUT/$name.$CMD.rc")"
