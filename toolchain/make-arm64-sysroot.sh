#!/usr/bin/env bash
# Builds an arm64 Debian 12 sysroot in a folder (default build-aarch64/sysroot) from Debian's
# arm64 packages, without touching the host's dpkg database: a private apt state directory
# resolves and downloads the arm64 -dev packages rdslam builds against, and each .deb is
# unpacked with `dpkg -x`. Multiarch -dev packages would conflict with the host's, hence a
# separate folder. Idempotent: an existing sysroot with a stamp file is reused.
#
# usage: toolchain/make-arm64-sysroot.sh [SYSROOT_DIR]
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
root="${1:-$here/build-aarch64/sysroot}"
state="$root.apt"
stamp="$root/.rdslam-sysroot-complete"

packages=(
  libc6-dev libstdc++-12-dev
  libopencv-dev libeigen3-dev libceres-dev libgoogle-glog-dev libgflags-dev
  liblcm-dev libglib2.0-dev libsystemd-dev libyaml-cpp-dev libturbojpeg0-dev
  libgtest-dev libgmock-dev libblas-dev liblapack-dev libatlas-base-dev libcamera-dev
)

# Debian 12 with its point-release and security updates, as a board's image would have.
sources="Types: deb
URIs: http://deb.debian.org/debian
Suites: bookworm bookworm-updates
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg

Types: deb
URIs: http://deb.debian.org/debian-security
Suites: bookworm-security
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg"

# The stamp records what the sysroot was made from: a changed package list or source rebuilds.
want="$(printf '%s\n' "${packages[@]}"; printf '%s\n' "$sources")"
if [[ -f "$stamp" ]] && [[ "$(cat "$stamp")" == "$want" ]]; then
  echo "make-arm64-sysroot: $root is complete"
  exit 0
fi

for tool in apt-get dpkg; do
  command -v "$tool" >/dev/null || { echo "make-arm64-sysroot: $tool not found" >&2; exit 1; }
done
[[ -f /usr/share/keyrings/debian-archive-keyring.gpg ]] || {
  echo "make-arm64-sysroot: /usr/share/keyrings/debian-archive-keyring.gpg missing" \
       "(apt-get install debian-archive-keyring)" >&2; exit 1; }
# A sysroot of an older package list, or of a run that stopped half-way, is made again from
# an empty folder; any other non-empty folder is left alone.
partial="$root/.rdslam-sysroot-partial"
if [[ -f "$stamp" || -f "$partial" ]]; then
  rm -rf "$root" "$state"
elif [[ -d "$root" && -n "$(ls -A "$root")" ]]; then
  echo "make-arm64-sysroot: $root is not empty and was not made by this script" >&2
  exit 1
fi

mkdir -p "$state"/etc/apt/{sources.list.d,preferences.d,apt.conf.d,trusted.gpg.d} \
  "$state"/var/lib/apt/lists/partial "$state"/var/cache/apt/archives/partial \
  "$state"/var/lib/dpkg "$root"
touch "$state/var/lib/dpkg/status" "$partial"
printf '%s\n' "$sources" > "$state/etc/apt/sources.list.d/debian.sources"
apt_opts=(
  -o "Dir=$state" -o "Dir::State::status=$state/var/lib/dpkg/status"
  -o "Dir::Etc::SourceParts=$state/etc/apt/sources.list.d"
  -o "Dir::Etc::sourcelist=/dev/null"
  -o APT::Architecture=arm64 -o "APT::Architectures::=arm64"
  -o Debug::NoLocking=1 -o APT::Install-Recommends=0 -o APT::Sandbox::User=root
)
echo "make-arm64-sysroot: resolving arm64 packages: ${packages[*]}"
apt-get "${apt_opts[@]}" update -qq
apt-get "${apt_opts[@]}" install -y -qq --download-only "${packages[@]}" >/dev/null
debs=("$state"/var/cache/apt/archives/*.deb)
echo "make-arm64-sysroot: unpacking ${#debs[@]} packages into $root"
for deb in "${debs[@]}"; do dpkg -x "$deb" "$root"; done
rm -rf "$state/var/cache/apt/archives"  # the .debs (about 260 MB) are not needed again

# Absolute symlinks inside the sysroot would point at the host: make them relative.
while IFS= read -r link; do
  target="$(readlink "$link")"
  [[ "$target" == /* ]] || continue
  ln -sfn "$(realpath -m --relative-to="$(dirname "$link")" "$root$target")" "$link"
done < <(find "$root" -type l)

# update-alternatives does not run under dpkg -x: link the reference BLAS/LAPACK into the
# library directory as the alternatives system would.
libdir="$root/usr/lib/aarch64-linux-gnu"
for alt in blas lapack; do
  [[ -d "$libdir/$alt" ]] || continue
  for f in "$libdir/$alt"/lib*.so*; do
    [[ -e "$libdir/$(basename "$f")" ]] || ln -s "$alt/$(basename "$f")" "$libdir/$(basename "$f")"
  done
done

printf '%s\n' "$want" > "$stamp"
rm -f "$partial"
echo "make-arm64-sysroot: done ($(du -sh "$root" | cut -f1))"
