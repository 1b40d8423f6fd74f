#!/usr/bin/env bash
# Render a fluidtex mesh.F.obj (with its .mtl and colour atlas) headless in
# Blender, from the same viewpoint as fluidtex's preview.F.png.
# Usage: tools/blender_render.sh MESH.obj OUT.png [SIZE [SAMPLES [--zoom Z] [--box x0,y0,z0,x1,y1,z1]]]
# Needs Blender >= 3.2 (the C++ OBJ importer); Debian: apt-get install blender.
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: $0 MESH.obj OUT.png [SIZE [SAMPLES]]" >&2
  exit 2
fi
obj=$(realpath "$1")
out=$(realpath -m "$2")
size=${3:-512}
samples=${4:-24}
# Anything after SAMPLES goes to the script as it is (--zoom Z, --box ...).
shift $(($# < 4 ? $# : 4))
script="$(cd "$(dirname "$0")" && pwd)/blender_render.py"
# --factory-startup: no user preferences or add-ons change the result.
# Blender exits 0 even when the script fails, so the log decides.
log=$(mktemp)
trap 'rm -f "$log"' EXIT
blender -b --factory-startup --python-exit-code 1 -P "$script" -- "$obj" "$out" --size "$size" --samples "$samples" "$@" >"$log" 2>&1 || {
  cat "$log" >&2
  exit 1
}
grep '^blender_render:' "$log"
test -s "$out"
