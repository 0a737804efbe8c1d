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
# The root file system: deploy/debian/make-root.sh's tarball (debootstrap
# from the machine's mirror), made once under build/ and shared with the
# Debian package's test.
top=$(cd "$(dirname "$0")/../.." && pwd)
tarball=$top/build/debian-12-minbase.tar
bash "$top/deploy/debian/make-root.sh" "$tarball"
"$docker" import "$tarball" "$tag" >/dev/null
echo "make-base: $tag made"
