#!/usr/bin/env bash
# The follow-up loop on the oracle cases (docs/diagnose.md, "seventh pass"), through
# the command line as a user runs it: for each pair (p*) and wrong-model (w*) case,
#   1. `volcomp diagnose` the measurement, writing the follow-up the report designs;
#   2. `volcomp simulate --followup` its readings on the TRUE machine (ref-trt) with
#      the case's own effects (truth.json), noise 0.3 µm, seed SEED;
#   3. `volcomp diagnose --followup` the measurement and the readings together.
# The readings are volcomp's simulation of the oracle's truth, not the oracle's.
#
#   bash examples/oracle_followup.sh [ORACLE_DIR] [SEED]
#
# ORACLE_DIR defaults to ../shared/data/oracle-cases; SEED to 1. Builds volcomp.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
oracle="$(cd "${1:-$here/../shared/data/oracle-cases}" && pwd)"
seed="${2:-1}"
cargo build --release --quiet --manifest-path "$here/Cargo.toml"
volcomp="$here/target/release/volcomp"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
said() { # selected effects and the verdict of a report
  python3 -c "import json,sys; r=json.load(open(sys.argv[1])); print('+'.join(sorted(r['selected'])) or 'nothing', '+ model verdict' if r['model_check']['mismatch'] else '')" "$1"
}
for dir in "$oracle"/p[0-9]* "$oracle"/w[0-9]*; do
  case_name="$(basename "$dir")"
  part="$(python3 -c "import json,sys; print(next(c['part'] for c in json.load(open(sys.argv[1])) if c['case'] == sys.argv[2]))" "$oracle/index.json" "$case_name")"
  machine="$here/machines/ref-trt.toml"
  [[ $case_name == w* ]] && machine="$oracle/machines/x1.4.toml"
  mapfile -t effects < <(python3 -c "import json,sys
for e in json.load(open(sys.argv[1]))['effects']:
    print('--effect'); print(e['name'] + ':' + ','.join(f'{k}={v}' for k, v in e['params'].items()))" "$dir/truth.json")
  truth="$(python3 -c "import json,sys; print('+'.join(sorted(e['name'] for e in json.load(open(sys.argv[1]))['effects'])) or 'nothing')" "$dir/truth.json")"
  rm -f "$work"/*
  "$volcomp" diagnose "$machine" "$oracle/$part" "$dir/measured.csv" --report "$work/before.json" --followup-program "$work/followup.nc" > /dev/null
  before="$(said "$work/before.json")"
  if [[ ! -f $work/followup.csv ]]; then
    echo "$case_name | truth $truth | before: $before | no follow-up designed"
    continue
  fi
  "$volcomp" simulate "$here/machines/ref-trt.toml" "$oracle/$part" "$dir/measured.csv" --followup "$work/followup.csv" -o "$work/readings.csv" "${effects[@]}" --noise-um 0.3 --seed "$seed" > /dev/null
  "$volcomp" diagnose "$machine" "$oracle/$part" "$dir/measured.csv" --report "$work/after.json" --followup "$work/readings.csv" > /dev/null
  echo "$case_name | truth $truth | before: $before | after: $(said "$work/after.json")"
done
