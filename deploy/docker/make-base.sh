#!/usr/bin/env bash
# make-base.sh [TAG]: a Debian 12 base image for deploy/docker/Dockerfile
# without any registry: debootstrap (minbase) from this machine's Debian
# mirror, imported into Docker as TAG (default locus-debian:12). Made once:
# an image already tagged TAG is kept. Its apt sources are this machine's
# bookworm, bookworm-updates and bookworm-security, so that the image gets
# the same package versions as the host. Needs root, debootstrap and a
# running Docker daemon (DOCKER: the client, default docker).
set -euo pipefail
tag=${1:-locus-debian:12}
docker=${DOCKER:-docker}
if "$docker" image inspect "$tag" >/dev/null 2>&1; then
  echo "make-base: $tag exists"
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
trap 'rm -rf "$root"' EXIT
echo "make-base: debootstrap bookworm from $mirror"
debootstrap --variant=minbase bookworm "$root" "$mirror" >"$root.log" 2>&1 ||
  { tail -20 "$root.log"; rm -f "$root.log"; exit 1; }
rm -f "$root.log"
{
  echo "deb $mirror bookworm main"
  echo "deb $mirror bookworm-updates main"
  [ -n "$security" ] && echo "deb $security bookworm-security main"
} >"$root/etc/apt/sources.list"
# Smaller and quieter: no package caches, no recommends in the image.
rm -rf "$root"/var/cache/apt/archives/*.deb "$root"/var/lib/apt/lists/*
printf 'APT::Install-Recommends "false";\nAPT::Install-Suggests "false";\n' \
  >"$root/etc/apt/apt.conf.d/99locus-no-recommends"
tar -C "$root" -c . | "$docker" import - "$tag" >/dev/null
echo "make-base: $tag made"
