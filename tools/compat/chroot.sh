# Mounting, entering and unmounting the compat root; sourced by the other compat scripts.
# The root sees the host's /proc, /sys (UCX inside the DOLFINx wheel probes it), a private /dev/shm
# for MPI shared memory, and the repository at /repo.

compat_mount() {
  local root=$1 repo=${2:-}
  mountpoint -q "$root/proc" || mount -t proc proc "$root/proc"
  mountpoint -q "$root/sys" || mount --bind /sys "$root/sys"
  mkdir -p "$root/dev/shm"
  mountpoint -q "$root/dev/shm" || mount -t tmpfs -o mode=1777 shm "$root/dev/shm"
  if [ -n "$repo" ]; then
    mkdir -p "$root/repo"
    mountpoint -q "$root/repo" || mount --bind "$repo" "$root/repo"
  fi
}

# Read-only bind mounts made inside the root (deepest first when unmounting).
compat_readonly_mounts=()

# Unmount whatever of ours is mounted, deepest first; safe to call any number of times.
compat_unmount_all() {
  local root=$1 target
  for target in "${compat_readonly_mounts[@]}"; do
    if mountpoint -q "$target" 2>/dev/null; then
      umount "$target" || umount -l "$target"
    fi
  done
  compat_readonly_mounts=()
  for target in repo dev/shm sys proc; do
    if mountpoint -q "$root/$target" 2>/dev/null; then
      umount "$root/$target" || umount -l "$root/$target"
    fi
  done
}

compat_chroot() {
  local root=$1
  shift
  chroot "$root" /usr/bin/env -i -C "${COMPAT_CWD:-/}" HOME=/root TERM="${TERM:-dumb}" LANG=C.UTF-8 \
    PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin "$@"
}
