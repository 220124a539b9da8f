#!/usr/bin/env bash
# Layering check (issue 21): the libraries depend one way only,
#   firmware_app -> drivers -> core,
# so core/ includes nothing from drivers/ or firmware_app/, and drivers/ nothing from
# firmware_app/. Prints each offending line and exits 1; prints a one-line summary when clean.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
bad=0
check() {  # check DIR PATTERN: DIR's sources must not include PATTERN
  local dir=$1 pattern=$2 hits
  hits=$(git ls-files "$dir/*.h" "$dir/*.hpp" "$dir/*.cpp" \
    | xargs -r grep -nE "^[[:space:]]*#[[:space:]]*include[[:space:]]*[<\"]($pattern)/" || true)
  if [[ -n "$hits" ]]; then
    echo "layering: $dir/ must not include $pattern/:" >&2
    echo "$hits" >&2
    bad=1
  fi
}
check core 'drivers|firmware_app'
check drivers 'firmware_app'
if (( bad )); then exit 1; fi
echo "layering: core/ includes nothing from drivers/ or firmware_app/, drivers/ nothing from firmware_app/"
