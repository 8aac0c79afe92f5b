#!/usr/bin/env bash
# Prove README's two commands on a fresh Debian 12 machine: build a clean root with mmdebstrap (only
# python3, make, git, ca-certificates, procps), clone this checkout's HEAD into it, run `make run` and
# `make test` there under chroot, print the wall time of each, and remove everything afterwards (also on
# failure or Ctrl-C).
#
#   scripts/fresh-machine.sh [--keep-tarball] [COMMAND ...]     default commands: "make run" "make test"
#
# Needs root (chroot, mounts). The root tarball is cached in $PETROLL_FRESH_CACHE (default
# /var/cache/petroll-fresh) and rebuilt when older than a week. Exit status: that of the first failing
# command, 0 when all pass.
set -uo pipefail
if [ "$(id -u)" -ne 0 ]; then
  echo "fresh-machine: needs root (chroot and mounts); run it as root, e.g. sudo scripts/fresh-machine.sh" >&2
  exit 2
fi
cd "$(dirname "$0")/.." || exit 2
project=$(pwd)
cache="${PETROLL_FRESH_CACHE:-/var/cache/petroll-fresh}"
tarball="$cache/bookworm.tar"
commands=("$@")
[ ${#commands[@]} -gt 0 ] || commands=("make run" "make test")

say() { echo "[fresh-machine] $*" >&2; }
fail() { echo "[fresh-machine] failed: $*" >&2; exit 2; }

mkdir -p "$cache" || fail "cannot create $cache; set PETROLL_FRESH_CACHE to a writable folder"
if [ -z "$(find "$tarball" -mtime -7 2>/dev/null)" ]; then
  if ! command -v mmdebstrap >/dev/null 2>&1; then
    say "installing mmdebstrap (Debian package)"
    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mmdebstrap; } >/dev/null 2>&1 \
      || fail "apt-get could not install mmdebstrap; install it by hand"
  fi
  say "building a fresh Debian 12 root (mmdebstrap, about 30 s)"
  start=$(date +%s)
  mmdebstrap --quiet --format=tar --variant=apt --include=python3,make,git,ca-certificates,procps \
      bookworm "$tarball.part" >/dev/null 2>&1 \
    || { rm -f "$tarball.part"; fail "mmdebstrap could not build the root (network to Debian's mirror?)"; }
  mv "$tarball.part" "$tarball"
  say "root built in $(( $(date +%s) - start )) s"
fi

work=$(mktemp -d /tmp/petroll-fresh.XXXXXX) || fail "mktemp"
root="$work/root"
cleanup() {
  for m in "$root/sys" "$root/dev" "$root/proc"; do
    mountpoint -q "$m" 2>/dev/null && umount -lR "$m" 2>/dev/null
  done
  # Remove only when nothing is mounted below any more (never follow into the host's /dev or /sys).
  if ! grep -q " $root/" /proc/mounts 2>/dev/null; then rm -rf "$work"; else say "left $work (still mounted)"; fi
}
trap cleanup EXIT
trap 'say "interrupted"; exit 130' INT TERM

mkdir -p "$root"
tar -xf "$tarball" -C "$root" || fail "cannot unpack $tarball; remove it to rebuild"
git clone -q "$project" "$root/petroll" || fail "git clone of $project"
(cd "$root/petroll" && git checkout -q "$(git -C "$project" rev-parse HEAD)") || fail "checkout of HEAD"
# The network as the host sees it: its resolver and the local certificate authorities it trusts (a proxy
# that re-signs HTTPS, as on corporate networks and this project's machines, is otherwise refused by pip).
cp /etc/resolv.conf "$root/etc/resolv.conf" 2>/dev/null || true
if compgen -G "/usr/local/share/ca-certificates/*.crt" >/dev/null; then
  cp /usr/local/share/ca-certificates/*.crt "$root/usr/local/share/ca-certificates/" \
    && chroot "$root" update-ca-certificates >/dev/null 2>&1 || fail "installing the host's local certificate authorities"
fi
mount -t proc proc "$root/proc" && mount --rbind /dev "$root/dev" && mount --make-rslave "$root/dev" \
  && mount --rbind /sys "$root/sys" && mount --make-rslave "$root/sys" || fail "mounting proc/dev/sys"

status=0
report=()
for command in "${commands[@]}"; do
  say "running '$command' in the fresh root"
  start=$(date +%s)
  chroot "$root" /usr/bin/env -i HOME=/root PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
      LANG=C.UTF-8 TERM=dumb bash -lc "cd /petroll && $command"
  rc=$?
  seconds=$(( $(date +%s) - start ))
  report+=("'$command': exit $rc, $seconds s")
  if [ $rc -ne 0 ]; then status=$rc; break; fi
done
for line in "${report[@]}"; do echo "fresh-machine: $line"; done
exit $status
