#!/usr/bin/env bash
# Installs the Debian 12 packages Locus needs to build, test and run.
# Idempotent: installs only what is missing; no network access otherwise.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  protobuf-compiler libprotobuf-dev protobuf-compiler-grpc libgrpc++-dev
  libglm-dev libopenimageio-dev openimageio-tools libspdlog-dev libgtest-dev libcli11-dev
  libtinyobjloader-dev libsqlite3-dev libssl-dev libzstd-dev zlib1g-dev
  # EXR files written and read without OpenImageIO (common/base/exr.cpp),
  # their blocks compressed and checked with libdeflate.
  libopenexr-dev libdeflate-dev
  # Metrics (prometheus-cpp: core and the pull endpoint); the dashboard's
  # HTTP server (cpp-httplib, header-only, on OpenSSL).
  prometheus-cpp-dev libcpp-httplib-dev
  # The dashboard's browser test (tests/dashboard/run.sh).
  chromium chromium-driver python3-selenium
  sqlite3 iproute2
  # Movies of a job's frames (the coordinator's and `locus render`'s
  # --movie: H.264 MP4, WebM, GIF); ffprobe for the movie tests.
  ffmpeg
  python3 python3-numpy python3-pil python3-matplotlib python3-openimageio python3-yaml
  # bench/peers: the Embree 3 Whitted caster (locus-embree-whitted, optional);
  # POV-Ray 3.7, the peer of bench/peers and bench/accuracy; GNU time for
  # each renderer's peak memory (bench/accuracy/run.py run_child).
  libembree-dev povray time
  # The Python client (client/python, docs/python.md); its stubs come from
  # protobuf-compiler-grpc's grpc_python_plugin, above.
  python3-grpcio python3-protobuf
  # TLS test certificates (tests/tls/make_certs.sh); libFuzzer targets:
  # clang, and libFuzzer itself (libclang_rt.fuzzer) from libclang-rt-14-dev.
  openssl clang libclang-rt-14-dev
  # Containers (tests/container/run.sh, deploy/): the engine, compose, and
  # debootstrap for the base image (deploy/docker/make-base.sh).
  docker.io docker-compose debootstrap
  # The Debian package (deploy/debian/, tests/package/run.sh): dpkg-shlibdeps
  # for its dependencies, help2man for its man pages, systemd-analyze to
  # verify its units and man, which it runs to find their Documentation=
  # pages (debootstrap, above, makes the root it installs into).
  dpkg-dev help2man systemd man-db
  # Workers on Slurm (deploy/slurm/, tests/slurm/run.sh): a one-node Slurm
  # started by the test itself (controller, node daemon, sbatch/srun/scancel)
  # and munge for its authentication.
  munge slurmctld slurmd slurm-client
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "install-deps: installing ${missing[*]}"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
# Wait for another apt (a second install-deps.sh, unattended upgrades)
# rather than fail on its lock.
$SUDO apt-get -o DPkg::Lock::Timeout=600 update -qq
$SUDO apt-get -o DPkg::Lock::Timeout=600 install -y -qq --no-install-recommends "${missing[@]}"
