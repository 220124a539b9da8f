#!/usr/bin/env bash
# Feeds recorded frames through ffmpeg into a v4l2loopback device, so rdslam reads them
# through the real kernel V4L2 path (`--set source=v4l2:/dev/videoN`), exactly as from a
# USB camera. For test rigs that can load the v4l2loopback module (root, matching kernel
# headers: Debian package v4l2loopback-dkms). Documented in docs/cameras.md.
#
# usage: toolchain/v4l2loopback-feed.sh [options] INPUT
#   INPUT             a video file, a folder of images, or a TUM (rgb/), KITTI (image_0/,
#                     image_l/) or EuRoC (mav0/cam0/data/) folder
#   --device DEV      loopback device to write (default: load the module as /dev/video42)
#   --size WxH        frame size written (default 640x480)
#   --fps F           frame rate (default 30)
#   --format F        yuyv (default) or mjpeg: what the "camera" offers
#   --loop            repeat the input forever (default: play once)
#   --dry-run         print the ffmpeg command instead of running it
#   --check           run the same ffmpeg pipeline into a null sink (no device needed):
#                     validates INPUT and the filters on machines without the module
#
# Then, in another shell:
#   rdslam sources                                   # shows "rdslam loopback" at DEV
#   RDSLAM_V4L2_TEST_DEVICE=DEV ctest --test-dir build -R test_v4l2_source
#   rdslam run --set source=v4l2:DEV --set v4l2.width=640 --set v4l2.height=480
set -euo pipefail

device=""
size="640x480"
fps=30
format=yuyv
loop=0
dry=0
check=0
input=""
while (($#)); do
  case "$1" in
    --device) device="$2"; shift 2 ;;
    --size) size="$2"; shift 2 ;;
    --fps) fps="$2"; shift 2 ;;
    --format) format="$2"; shift 2 ;;
    --loop) loop=1; shift ;;
    --dry-run) dry=1; shift ;;
    --check) check=1; shift ;;
    -h|--help) sed -n '2,25p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "v4l2loopback-feed: unknown option '$1' (see --help)" >&2; exit 2 ;;
    *) [[ -z "$input" ]] || { echo "v4l2loopback-feed: one INPUT only" >&2; exit 2; }
       input="$1"; shift ;;
  esac
done
[[ -n "$input" ]] || { echo "v4l2loopback-feed: INPUT is required (see --help)" >&2; exit 2; }
[[ "$size" =~ ^[0-9]+x[0-9]+$ ]] || { echo "v4l2loopback-feed: --size must be WxH" >&2; exit 2; }
[[ "$fps" =~ ^[0-9]+([.][0-9]+)?$ ]] || { echo "v4l2loopback-feed: --fps must be a number" >&2; exit 2; }
case "$format" in
  yuyv) codec=(-pix_fmt yuyv422 -c:v rawvideo) ;;
  # ffmpeg's v4l2 output maps the MJPEG codec to V4L2_PIX_FMT_MJPEG; 4:2:2 like webcams.
  mjpeg) codec=(-pix_fmt yuvj422p -c:v mjpeg -q:v 3) ;;
  *) echo "v4l2loopback-feed: --format must be yuyv or mjpeg" >&2; exit 2 ;;
esac
command -v ffmpeg >/dev/null || { echo "v4l2loopback-feed: ffmpeg not installed" >&2; exit 1; }

# Input: a video file, or an image sequence (a TUM folder's rgb/ or any folder of images).
in_args=()
if [[ -d "$input" ]]; then
  dir="$input"
  for sub in rgb image_0 image_l mav0/cam0/data; do  # TUM, KITTI (grey/left), EuRoC
    if [[ -d "$input/$sub" ]]; then dir="$input/$sub"; break; fi
  done
  ext=""
  for e in png jpg jpeg pgm ppm bmp; do
    if compgen -G "$dir/*.$e" >/dev/null; then ext="$e"; break; fi
  done
  [[ -n "$ext" ]] || { echo "v4l2loopback-feed: no images in $dir" >&2; exit 1; }
  in_args=(-framerate "$fps" -pattern_type glob -i "$dir/*.$ext")
elif [[ -f "$input" ]]; then
  in_args=(-i "$input")
else
  echo "v4l2loopback-feed: no such file or folder: $input" >&2; exit 1
fi
((loop)) && in_args=(-stream_loop -1 "${in_args[@]}")

w="${size%x*}"
h="${size#*x}"
# -re: write in real time, as a camera would deliver; fps filter: a steady camera rate.
filters="scale=${w}:${h},fps=${fps}"
if ((check)); then
  out=(-frames:v 10 -f null -)
else
  if [[ -z "$device" ]]; then
    device=/dev/video42
    if [[ ! -e "$device" ]]; then
      if ((dry)); then
        echo "# would run: modprobe v4l2loopback devices=1 video_nr=42 card_label=\"rdslam loopback\" exclusive_caps=1"
      else
        command -v modprobe >/dev/null || { echo "v4l2loopback-feed: no modprobe here: load v4l2loopback on a machine that can, or pass --device" >&2; exit 1; }
        modprobe v4l2loopback devices=1 video_nr=42 card_label="rdslam loopback" exclusive_caps=1 || {
          echo "v4l2loopback-feed: cannot load v4l2loopback (root? apt-get install v4l2loopback-dkms)" >&2; exit 1; }
      fi
    fi
  fi
  if ((!dry)); then
    [[ -c "$device" ]] || { echo "v4l2loopback-feed: $device is not a character device" >&2; exit 1; }
    name="$(cat "/sys/class/video4linux/$(basename "$device")/name" 2>/dev/null || true)"
    [[ "$name" == *oopback* || "$name" == *rdslam* ]] || {
      echo "v4l2loopback-feed: $device ('$name') is not a v4l2loopback device; refusing to write" >&2; exit 1; }
  fi
  out=(-f v4l2 "$device")
fi
cmd=(ffmpeg -nostdin -hide_banner -loglevel error -re "${in_args[@]}" -vf "$filters" "${codec[@]}" "${out[@]}")
if ((dry)); then
  printf '%q ' "${cmd[@]}"; echo
  exit 0
fi
echo "v4l2loopback-feed: ${input} -> ${device:-null sink} (${format} ${size} @ ${fps} fps)" >&2
exec "${cmd[@]}"
