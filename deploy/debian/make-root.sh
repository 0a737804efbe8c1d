#!/usr/bin/env bash
# make-root.sh TARBALL: a Debian 12 (bookworm) minbase root file system as a
# tar archive, made with debootstrap from this machine's Debian mirror.
# Made once: an existing TARBALL is kept (delete it to make a fresh one).
# Two users share it: deploy/docker/make-base.sh imports it into Docker as
# the images' base, tests/package/run.sh installs the .deb into a copy of
# it. Its apt sources are this machine's bookworm, bookworm-updates and
# bookworm-security, so that what is installed into it gets the host's
# package versions; no package lists or .debs are kept, and apt installs
# no recommends. Needs root and debootstrap. Concurrent callers wait for
# the one making it (a lock file next to TARBALL).
set -euo pipefail
[ $# -eq 1 ] || { echo "usage: $0 TARBALL" >&2; exit 2; }
out=$1
[ -s "$out" ] && exit 0
mkdir -p "$(dirname "$out")"
exec 9>"$out.lock"
flock 9
if [ -s "$out" ]; then
  echo "make-root: $out made meanwhile"
  exit 0
fi
# The machine's configured Debian mirrors (apt's own view of its sources).
uri_of() {
  apt-get indextargets --format '$(RELEASE) $(REPO_URI)' 2>/dev/null | awk -v r="$1" '$1 == r {print $2; exit}'
}
mirror=$(uri_of bookworm)
mirror=${mirror:-http://deb.debian.org/debian/}
security=$(uri_of bookworm-security)
root=$(mktemp -d /var/tmp/locus-debian.XXXXXX)
trap 'rm -rf "$root" "$root.log" "$out.part"' EXIT
echo "make-root: debootstrap bookworm from $mirror"
debootstrap --variant=minbase bookworm "$root" "$mirror" >"$root.log" 2>&1 ||
  { tail -20 "$root.log"; exit 1; }
{
  echo "deb $mirror bookworm main"
  echo "deb $mirror bookworm-updates main"
  [ -n "$security" ] && echo "deb $security bookworm-security main"
} >"$root/etc/apt/sources.list"
# / as on any Debian system (mktemp made it 0700).
chmod 755 "$root"
# Smaller: no package caches, no recommends.
rm -rf "$root"/var/cache/apt/archives/*.deb "$root"/var/lib/apt/lists/*
printf 'APT::Install-Recommends "false";\nAPT::Install-Suggests "false";\n' \
  >"$root/etc/apt/apt.conf.d/99locus-no-recommends"
tar -C "$root" -c . >"$out.part"
mv "$out.part" "$out"
echo "make-root: $out made"
