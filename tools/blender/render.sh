#!/bin/sh
# Render one Blender room sequence as a TUM RGB-D folder (tools/blender/render_room.py).
#
#   tools/blender/render.sh VARIANT OUTDIR [more render_room.py options]
#   e.g. tools/blender/render.sh walking /work/blender_out/walking_s1 --seed 1 --frames 150
#
# Runs Blender in the background at low priority (nice 15) on one thread. Eevee (the
# default engine) needs an OpenGL context: without $DISPLAY it runs under xvfb-run with
# Mesa's software rasteriser, also limited to one thread (LP_NUM_THREADS=1).
# Needs Debian's `blender` and `xvfb` packages: apt-get install -y blender xvfb
set -eu
if [ $# -lt 2 ]; then
  echo "usage: $0 static|walking|rearranged|dominant OUTDIR [render_room.py options]" >&2
  exit 2
fi
variant=$1
out=$2
shift 2
here=$(cd "$(dirname "$0")" && pwd)
export LP_NUM_THREADS="${LP_NUM_THREADS:-1}"
run="nice -n 15 blender -b -noaudio --factory-startup -t 1 -P $here/render_room.py -- --scene $variant --out $out"
if [ -z "${DISPLAY:-}" ]; then
  exec xvfb-run -a -s "-screen 0 1280x1024x24" $run "$@"
fi
exec $run "$@"
