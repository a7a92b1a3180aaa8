#!/usr/bin/env bash
# The main job on the built-in example (placeholder until the stages land).
set -euo pipefail
bin=${1:-build/kinesplat}
out=${2:-demo-out}
"$bin" info
