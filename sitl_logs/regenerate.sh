#!/usr/bin/env bash
# Regenerate sitl_logs/ exactly from config/scenarios/ (each scenario file fixes its seed).
#   sitl_logs/regenerate.sh          rewrite the logs, truth CSVs and fault sidecars
#   sitl_logs/regenerate.sh --check  regenerate into a temporary directory and compare
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
NAMES=(
  px4_landing_nominal
  px4_hover_gnss_step
  px4_gnss_ramp
  px4_baro_ramp
  ardupilot_rng_dropout
  ardupilot_input_faults
)
out=sitl_logs
if [[ "${1:-}" == "--check" ]]; then
  out=$(mktemp -d)
  trap 'rm -rf "$out"' EXIT
fi
for name in "${NAMES[@]}"; do
  "$PY" -c 'import sys; from mavnav.cli import main; sys.exit(main())' simulate \
    "config/scenarios/$name.yaml" -o "$out/$name.tlog" --truth "$out/$name.truth.csv"
done
if [[ "$out" != sitl_logs ]]; then
  status=0
  for name in "${NAMES[@]}"; do
    for ext in tlog truth.csv faults.json; do
      cmp -s "$out/$name.$ext" "sitl_logs/$name.$ext" || { echo "differs: sitl_logs/$name.$ext"; status=1; }
    done
  done
  [[ $status == 0 ]] && echo "sitl_logs: all files match their scenarios"
  exit $status
fi
