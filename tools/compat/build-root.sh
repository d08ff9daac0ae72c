#!/usr/bin/env bash
# Build (once) the Debian trixie root that hosts the DOLFINx 0.9 and 0.11 test lanes.
#
# Usage: tools/compat/build-root.sh ROOT
#
# Each stage leaves a stamp file in ROOT/.compat-stages once it has completed; a stage without its
# stamp is redone from scratch (debootstrap, venv) or resumed (apt, which is idempotent), so an
# interrupted build is never silently reused.
set -euo pipefail

root=$(realpath -m "${1:?usage: build-root.sh ROOT}")
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=tools/compat/chroot.sh
source "$here/chroot.sh"

suite=trixie
mirror=${COMPAT_MIRROR:-http://deb.debian.org/debian}
stages=$root/.compat-stages
# Debian trixie's own DOLFINx 0.9 lane, plus what the tests and demos import.
apt_packages=(
  python3-dolfinx-real python3-numba python3-pytest python3-pytest-xdist python3-meshio
  python3-h5py python3-scipy
  python3-matplotlib python3-tqdm python3-gmsh openmpi-bin python3-venv python3-pip
  ca-certificates paraview python3-paraview python3-pil xvfb
)
# The PyPI lane: DOLFINx 0.11 wheel with its own MPICH, and the same test dependencies from PyPI.
# h5py < 3.16: its wheels from 3.16 on bundle HDF5 2.0, while the DOLFINx wheel loads HDF5 1.14
# (through PETSc) into the same process, and h5py then fails with "Not a datatype".
pip_packages=(
  dolfinx-solver-real numba pytest pytest-xdist meshio "h5py<3.16" scipy matplotlib tqdm gmsh
  pillow ipctk==1.6.1
)
# What Debian does not package, for the trixie lane's system Python: IPC Toolkit (its wheels
# need only NumPy and SciPy, which Debian's packages give).
system_pip_packages=(ipctk==1.6.1)
venv=/opt/dolfinx-wheel

stage_done() { [ -e "$stages/$1" ]; }
# The package stages are keyed on their lists, so adding a package installs it into a kept root.
list_key() { printf '%s\n' "$@" | sha256sum | cut -c1-12; }
apt_stage=apt-$(list_key "${apt_packages[@]}")
venv_stage=venv-$(list_key "${pip_packages[@]}")
system_pip_stage=system-pip-$(list_key "${system_pip_packages[@]}")
mark_done() { mkdir -p "$stages" && touch "$stages/$1"; }

ensure_debootstrap() {
  if ! dpkg-query -W -f='${Status}' debootstrap 2>/dev/null | grep -q "install ok installed"; then
    echo "installing Debian package: debootstrap"
    local sudo=""
    [ "$(id -u)" = 0 ] || sudo=sudo
    $sudo apt-get update -q
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends debootstrap
  fi
}

if ! stage_done debootstrap; then
  ensure_debootstrap
  # A half-made root cannot be resumed by debootstrap; start over, but never through live mounts.
  compat_unmount_all "$root"
  # The repository bind mount lives on the same filesystem, so --one-file-system alone would not
  # keep rm out of it: refuse outright while anything is mounted below the root.
  if findmnt -rn -o TARGET | grep -q "^$root/"; then
    echo "error: something is still mounted under $root; not deleting it" >&2
    exit 1
  fi
  for attempt in 1 2 3; do
    rm -rf --one-file-system "$root"
    mkdir -p "$(dirname "$root")"
    echo "debootstrap $suite into $root (a few minutes; attempt $attempt)"
    if debootstrap --variant=minbase "$suite" "$root" "$mirror"; then
      mark_done debootstrap
      break
    fi
    [ "$attempt" = 3 ] && exit 1
    sleep 10
  done
fi

# Always refresh: the host's resolver and CA certificates can change between runs.
cp /etc/resolv.conf "$root/etc/resolv.conf"
mkdir -p "$root/usr/local/share/compat-host-ca"
cp /etc/ssl/certs/ca-certificates.crt "$root/usr/local/share/compat-host-ca/ca-certificates.crt"

compat_mount "$root"
trap 'compat_unmount_all "$root"' EXIT
# A signal ends the script through exit, so the EXIT trap unmounts in every case.
trap 'exit 130' INT
trap 'exit 143' TERM

if ! stage_done "$apt_stage"; then
  echo "installing trixie packages: ${apt_packages[*]}"
  compat_chroot "$root" env DEBIAN_FRONTEND=noninteractive bash -euo pipefail -c '
    printf "Acquire::Retries \"5\";\n" > /etc/apt/apt.conf.d/80-retries
    apt-get update -q
    apt-get install -y -q --no-install-recommends "$@"
    apt-get clean
  ' apt "${apt_packages[@]}"
  mark_done "$apt_stage"
fi

if ! stage_done "$venv_stage"; then
  echo "creating the DOLFINx wheel venv: ${pip_packages[*]}"
  compat_chroot "$root" bash -euo pipefail -c '
    rm -rf "$1"
    python3 -m venv "$1"
    shift
    PIP_CERT=/usr/local/share/compat-host-ca/ca-certificates.crt \
      "$0"/bin/pip install -q --retries 5 --no-cache-dir "$@"
  ' "$venv" "$venv" "${pip_packages[@]}"
  mark_done "$venv_stage"
fi

if ! stage_done "$system_pip_stage"; then
  echo "installing into trixie's Python from PyPI: ${system_pip_packages[*]}"
  compat_chroot "$root" env PIP_CERT=/usr/local/share/compat-host-ca/ca-certificates.crt \
    python3 -m pip install -q --retries 5 --no-cache-dir --no-deps --break-system-packages \
    "${system_pip_packages[@]}"
  mark_done "$system_pip_stage"
fi
