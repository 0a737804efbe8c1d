#!/usr/bin/env bash
# tests/package/run.sh BIN_DIR SOURCE_DIR BUILD_DIR (CTest debian_package):
# the Debian package, built and installed into a fresh Debian 12 root.
#
#  1. cpack -G DEB in BUILD_DIR (into BUILD_DIR/package/); its Depends name
#     the package of every library the binaries link directly.
#  2. A copy of the minbase root BUILD_DIR/debian-12-minbase.tar
#     (deploy/debian/make-root.sh: debootstrap, made once), where apt
#     installs the .deb and resolves its dependencies from this machine's
#     Debian mirror. The copy (1.3 GB) is on a tmpfs when 4 GiB of memory
#     are available (on this disk, otherwise), mounted in a mount namespace
#     of the test's own: it goes away with the test, however the test ends.
#     Each command in the root runs under chroot in mount and PID
#     namespaces of its own, with its own /proc.
#  3. In the root: the binaries and the image plugin (/usr/lib/locus) load,
#     a TIFF render through the plugin, the user `locus` and /var/lib/locus,
#     the units, the conffiles, the man pages; `locus render` of a scene at
#     64x48 with --workers 0 equals this build's exactly (the same bytes;
#     the same pixels, should the mirror's libraries encode PNG otherwise).
#  4. The units' command lines, as systemd builds them from the installed
#     unit files and /etc/locus (EnvironmentFile=, specifiers, $VAR), run in
#     the root as the unit's User= with no new privileges and no
#     capabilities, in a network namespace with only a loopback: the
#     coordinator and 2 worker instances render a job equal to the same
#     render; SIGTERM drains the coordinator, which exits 0 within the
#     unit's TimeoutStopSec. Also the embedded farm of /usr/bin/locus.
#  5. systemd installed in the root: `systemd-analyze verify --root` of both
#     units is silent (it also checks the binaries and the man pages the
#     units name), and `systemd-analyze security --offline` rates each at
#     most 2.0; --drain-ms in coordinator.conf fits in TimeoutStopSec.
#  6. Reinstalling keeps an edited conffile; purging removes the binaries,
#     units and /etc/locus but keeps the user and the job store.
#
# No systemd is booted: the sandbox options themselves (ProtectSystem=,
# SystemCallFilter=, ...) are verified and rated, not enforced. Needs root,
# debootstrap and the Debian mirror; no skip code: a root that cannot be
# made or a service that cannot start fails the test.
set -uo pipefail
[ $# -eq 3 ] || { echo "usage: $0 BIN_DIR SOURCE_DIR BUILD_DIR" >&2; exit 2; }
[ "$(id -u)" -eq 0 ] || { echo "FAIL: needs root (debootstrap, chroot, namespaces)"; exit 1; }
# Everything below in a mount namespace of its own (see 2.).
if [ -z "${LOCUS_PACKAGE_TEST_NS:-}" ]; then
  LOCUS_PACKAGE_TEST_NS=1 exec unshare --mount --propagation private bash "$0" "$@"
fi
bin=$(realpath "$1") src=$(realpath "$2") build=$(realpath "$3")
plugin=$bin/../lib/locus/liblocus-image-io.so  # common/base/image_plugin.h
. "$src/tests/farm_lib.sh"  # same_pixels
start=$SECONDS
fails=0
ok() { echo "  ok: $*"; }
bad() { echo "  FAIL: $*"; fails=$((fails + 1)); }
die() { echo "FAIL: $*"; exit 1; }
step() { echo "[$((SECONDS - start)) s] $*"; }

for tool in cpack debootstrap unshare chroot setpriv systemd-analyze man ip readelf idiff; do
  command -v "$tool" >/dev/null || die "$tool is missing (bash deploy/local/install-deps.sh)"
done

tmp=$(mktemp -d /var/tmp/locus-package.XXXXXX)
root=$tmp/root
cleanup() {
  # Should a mount remain under the tree, it is left rather than deleted
  # through.
  mountpoint -q "$root" && umount "$root"
  if grep -q " $tmp/" /proc/self/mountinfo; then
    echo "package test: something is still mounted under $tmp; left in place"
  else
    rm -rf "$tmp"
  fi
}
trap cleanup EXIT

# in_root CMD...: CMD in the root, its own /proc, a clean environment.
in_root() {
  unshare --mount --pid --fork --mount-proc="$root/proc" \
    chroot "$root" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root LANG=C.UTF-8 \
    DEBIAN_FRONTEND=noninteractive "$@"
}
# same_image A B: identical files, or identical pixels (same_pixels, of
# tests/farm_lib.sh: other library versions encode differently, and the
# farm joins a PNG frame from its bands' streams).
same_image() {
  cmp -s "$1" "$2" || same_pixels "$1" "$2"
}

# ---- 1. the package
step "cpack -G DEB in $build"
rm -rf "$build/package"
(cd "$build" && cpack -G DEB -B "$build/package") >"$tmp/cpack.log" 2>&1 ||
  { tail -30 "$tmp/cpack.log"; die "cpack failed"; }
debs=("$build"/package/locus_*.deb)
[ ${#debs[@]} -eq 1 ] && [ -f "${debs[0]}" ] || die "cpack made no single locus_*.deb: ${debs[*]}"
deb=${debs[0]}
ok "$(basename "$deb") ($(du -k "$deb" | cut -f1) KiB)"
depends=$(dpkg-deb -f "$deb" Depends)
# The package of each library the binaries link directly must be a
# dependency (dpkg-shlibdeps); the packages' own dependencies bring the rest.
dep_names=$(tr ',' '\n' <<<"$depends" | awk '{print $1}')
# provides PKG: PKG and the names it provides (libspdlog1.10 provides the
# libspdlog1.10-fmt9 its shlibs name).
provides() {
  echo "$1"
  dpkg-query -W -f='${Provides}\n' "$1" 2>/dev/null | tr ',' '\n' | awk 'NF {print $1}'
}
missing=
for lib in $(for b in "$bin/locus" "$bin/locus-coordinator" "$bin/locus-worker" "$plugin"; do
               readelf -d "$b" | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p'
             done | sort -u); do
  path=$(ldconfig -p | awk -v l="$lib" '$1 == l && $NF ~ /^\// {print $NF; exit}')
  [ -n "$path" ] || { missing+=" $lib(unresolved)"; continue; }
  # By file name: /lib and /usr/lib are one directory (merged /usr), dpkg
  # knows a file under the one its package names.
  real=$(readlink -f "$path")
  pkgs=$(dpkg -S "*/${real##*/}" 2>/dev/null | sed 's/: .*//' | tr ',' '\n' | sed 's/^ *//; s/:.*//' | sort -u)
  [ -n "$pkgs" ] || { missing+=" $lib(no package)"; continue; }
  found=0
  for name in $(for pkg in $pkgs; do provides "$pkg"; done); do
    grep -qxF "$name" <<<"$dep_names" && found=1
  done
  [ $found = 1 ] || missing+=" $(echo $pkgs)($lib)"
done
[ -z "$missing" ] && ok "Depends names the package of every linked library" ||
  bad "Depends lacks:$missing (Depends: $depends)"

# ---- 2. a fresh Debian 12 root and apt
tarball=$build/debian-12-minbase.tar
step "root from $tarball (deploy/debian/make-root.sh; made once)"
bash "$src/deploy/debian/make-root.sh" "$tarball" || die "cannot make the Debian 12 root"
mkdir "$root"
if [ "$(awk '$1 == "MemAvailable:" {print int($2 / 1048576)}' /proc/meminfo)" -ge 4 ]; then
  mount -t tmpfs -o size=3g,mode=755 locus-package-root "$root" || die "cannot mount a tmpfs on $root"
fi
tar -C "$root" -xf "$tarball" || die "cannot unpack $tarball"
chmod 755 "$root"
cp -L /etc/resolv.conf "$root/etc/resolv.conf"
cp "$deb" "$root/tmp/"
cp "$src/scenes/simple/spheres.json" "$root/tmp/spheres.json"
step "apt-get install ./$(basename "$deb") in the root"
in_root apt-get -q -o APT::Sandbox::User=root update >"$tmp/apt.log" 2>&1 ||
  { tail -20 "$tmp/apt.log"; die "apt-get update in the root"; }
in_root apt-get -q -y -o APT::Sandbox::User=root install "/tmp/$(basename "$deb")" >>"$tmp/apt.log" 2>&1 ||
  { tail -30 "$tmp/apt.log"; die "apt-get install of the package in the root"; }
ok "installed: $(grep -Eo '[0-9]+ newly installed' "$tmp/apt.log" | head -1), $(grep -E '^Need to get' "$tmp/apt.log" | head -1)"

# ---- 3. what is installed
step "installed files"
[ "$(in_root dpkg-query -W -f='${Status}' locus)" = "install ok installed" ] && ok "dpkg: locus installed" ||
  bad "locus is not installed"
ldd_out=$(in_root ldd /usr/bin/locus /usr/bin/locus-coordinator /usr/bin/locus-worker \
  /usr/lib/locus/liblocus-image-io.so 2>&1)
grep -q "not found" <<<"$ldd_out" && bad "libraries missing in the root: $(grep "not found" <<<"$ldd_out" | sort -u | tr '\n' ' ')" ||
  ok "the three binaries and the image plugin (/usr/lib/locus) find every library"
for b in locus locus-coordinator locus-worker; do
  in_root "/usr/bin/$b" --help >"$tmp/$b.help" 2>&1 && ok "/usr/bin/$b --help" || bad "/usr/bin/$b --help fails"
done
units=$root/usr/lib/systemd/system
for f in "$units/locus-coordinator.service" "$units/locus-worker@.service" \
         "$root/etc/locus/coordinator.conf" "$root/etc/locus/worker.conf"; do
  [ -f "$f" ] || bad "missing ${f#"$root"}"
done
conffiles=$(in_root dpkg-query -W -f='${Conffiles}\n' locus)
grep -q "/etc/locus/coordinator.conf " <<<"$conffiles" && grep -q "/etc/locus/worker.conf " <<<"$conffiles" &&
  ok "units installed; /etc/locus/coordinator.conf and worker.conf are conffiles" || bad "conffiles: $conffiles"
IFS=: read -r _ _ uid gid _ home shell <<<"$(in_root getent passwd locus)"
if [ -n "${uid:-}" ] && [ "$uid" -lt 1000 ] && [ "$home" = /var/lib/locus ] && [ "$shell" = /usr/sbin/nologin ] &&
   [ "$(in_root getent group locus | cut -d: -f3)" = "$gid" ]; then
  ok "system user locus (uid $uid, group locus, home /var/lib/locus, no shell)"
else
  bad "user locus: uid=${uid:-none} home=${home:-} shell=${shell:-}"
fi
[ "$(in_root stat -c '%U:%G %a' /var/lib/locus)" = "locus:locus 750" ] && ok "/var/lib/locus locus:locus 750" ||
  bad "/var/lib/locus: $(in_root stat -c '%U:%G %a' /var/lib/locus 2>&1)"
# grep -c, not -q: it reads zcat's output to the end (tests/farm_lib.sh, prints).
for page in locus locus-coordinator locus-worker; do
  f=$root/usr/share/man/man1/$page.1.gz
  [ -f "$f" ] && zcat "$f" | grep -c "^\.TH" >/dev/null || { bad "man page $page(1) missing"; continue; }
done
zcat "$root/usr/share/man/man1/locus-coordinator.1.gz" | grep -c 'drain\\-ms' >/dev/null &&
  zcat "$root/usr/share/man/man1/locus.1.gz" | grep -c '^\.SS "locus render"' >/dev/null &&
  zcat "$root/usr/share/man/man1/locus-worker.1.gz" | grep -c 'abandon\\-grace' >/dev/null &&
  ok "man pages: locus(1) with each subcommand, locus-coordinator(1), locus-worker(1)" || bad "man pages' content"

step "locus render in the root == this build's"
"$bin/locus" render "$src/scenes/simple/spheres.json" --size 64x48 --workers 0 -o "$tmp/host.png" \
  >"$tmp/host-render.log" 2>&1 || { cat "$tmp/host-render.log"; die "host render"; }
in_root /usr/bin/locus render /tmp/spheres.json --size 64x48 --workers 0 -o /tmp/root.png \
  >"$tmp/root-render.log" 2>&1 && same_image "$tmp/host.png" "$root/tmp/root.png" &&
  ok "/usr/bin/locus render --workers 0 == $bin/locus render ($(cmp -s "$tmp/host.png" "$root/tmp/root.png" && echo same bytes || echo same pixels))" ||
  { bad "render in the root"; cat "$tmp/root-render.log"; }
# A TIFF goes through the image plugin, which the root's locus loads from
# /usr/lib/locus.
"$bin/locus" render "$src/scenes/simple/spheres.json" --size 64x48 --workers 0 -o "$tmp/host.tif" \
  >"$tmp/host-tif.log" 2>&1 || { cat "$tmp/host-tif.log"; die "host render (TIFF)"; }
in_root /usr/bin/locus render /tmp/spheres.json --size 64x48 --workers 0 -o /tmp/root.tif \
  >"$tmp/root-tif.log" 2>&1 && same_pixels "$tmp/host.tif" "$root/tmp/root.tif" &&
  ok "/usr/bin/locus render -o root.tif (the image plugin) == $bin/locus render" ||
  { bad "TIFF render in the root"; cat "$tmp/root-tif.log"; }

# ---- 4. the units' command lines
# unit_command UNIT INSTANCE: the ExecStart= command line systemd builds
# for the installed UNIT, one word per line: its EnvironmentFile=s (a
# leading - : optional) read from the root, the specifiers %i %l %H %%,
# $VAR split into words and ${VAR} one word. Refuses what it does not
# model (quotes and escapes in ExecStart=, continued lines).
unit_command() {
  local unit=$1 inst=$2 line f opt key val w name host short
  local -A vars=()
  local -a out=()
  host=$(hostname) short=$(hostname -s)
  while IFS= read -r line; do
    [[ $line == EnvironmentFile=* ]] || continue
    f=${line#EnvironmentFile=} opt=0
    [[ $f == -* ]] && { opt=1; f=${f#-}; }
    f=${f//%i/$inst}
    if [ ! -f "$root$f" ]; then
      [ $opt = 1 ] && continue
      echo "unit_command: $unit: $f is missing" >&2; return 1
    fi
    while IFS= read -r line || [ -n "$line" ]; do
      line=${line#"${line%%[![:space:]]*}"}
      [[ -z $line || $line == \#* || $line == \;* ]] && continue
      [[ $line == *\\ ]] && { echo "unit_command: continued line in $f" >&2; return 1; }
      key=${line%%=*} val=${line#*=}
      [[ $val =~ ^\"(.*)\"$ ]] && val=${BASH_REMATCH[1]}
      vars[$key]=$val
    done <"$root$f"
  done <"$units/$unit"
  line=$(grep -m1 '^ExecStart=' "$units/$unit") || { echo "unit_command: no ExecStart in $unit" >&2; return 1; }
  line=${line#ExecStart=}
  [[ $line == *[\"\'\\]* ]] && { echo "unit_command: quotes in $unit's ExecStart" >&2; return 1; }
  line=${line//%%/$'\x01'} line=${line//%i/$inst} line=${line//%l/$short} line=${line//%H/$host}
  line=${line//$'\x01'/%}
  set -f
  for w in $line; do
    if [[ $w =~ ^\$([A-Za-z_][A-Za-z0-9_]*)$ ]]; then
      name=${BASH_REMATCH[1]}
      out+=(${vars[$name]-})
    elif [[ $w =~ ^\$\{([A-Za-z_][A-Za-z0-9_]*)\}$ ]]; then
      name=${BASH_REMATCH[1]}
      out+=("${vars[$name]-}")
    else
      out+=("$w")
    fi
  done
  set +f
  printf '%s\n' "${out[@]}"
}
unit_key() { sed -n "s/^$2=//p" "$units/$1" | tail -1; }

step "the units' command lines run as their user, loopback only"
unit_command locus-coordinator.service "" >"$tmp/coord.cmd" || die "the coordinator's command line"
unit_command locus-worker@.service 1 >"$tmp/worker1.cmd" || die "the worker's command line"
unit_command locus-worker@.service 2 >"$tmp/worker2.cmd" || die "the worker's command line"
mapfile -t coord_cmd <"$tmp/coord.cmd"
mapfile -t worker1_cmd <"$tmp/worker1.cmd"
mapfile -t worker2_cmd <"$tmp/worker2.cmd"
echo "  coordinator: ${coord_cmd[*]}"
echo "  worker 1:    ${worker1_cmd[*]}"
[ "$(unit_key locus-coordinator.service User)" = locus ] && [ "$(unit_key locus-worker@.service User)" = locus ] &&
  ok "both units run as User=locus" || bad "the units' User="
stop_timeout=$(unit_key locus-coordinator.service TimeoutStopSec)
# run_as UNIT: the prefix that gives a command the unit's user, group,
# working directory and umask, no new privileges and no capabilities.
run_as() {
  local user group dir mask
  user=$(unit_key "$1" User) group=$(unit_key "$1" Group) dir=$(unit_key "$1" WorkingDirectory) mask=$(unit_key "$1" UMask)
  printf '%q ' setpriv --reuid="$user" --regid="$group" --init-groups --no-new-privs --inh-caps=-all \
    --bounding-set=-all -- /bin/sh -c "umask ${mask:-0022} && cd ${dir:-/} && exec \"\$@\"" -
}
{
  echo 'set -u'
  echo 'cd /tmp'
  # exec: started with &, the PID is the program's own.
  printf 'coordinator() { exec %s %s; }\n' "$(run_as locus-coordinator.service)" "$(printf '%q ' "${coord_cmd[@]}")"
  printf 'worker1() { exec %s %s; }\n' "$(run_as locus-worker@.service)" "$(printf '%q ' "${worker1_cmd[@]}")"
  printf 'worker2() { exec %s %s; }\n' "$(run_as locus-worker@.service)" "$(printf '%q ' "${worker2_cmd[@]}")"
  cat <<'EOF'
coordinator >/tmp/coordinator.log 2>&1 & cpid=$!
up=0
for _ in $(seq 100); do
  locus status --farm 127.0.0.1:7000 >/dev/null 2>&1 && { up=1; break; }
  kill -0 "$cpid" 2>/dev/null || break
  sleep 0.1
done
[ $up = 1 ] || { echo "coordinator: not serving"; exit 10; }
worker1 >/tmp/worker1.log 2>&1 & w1=$!
worker2 >/tmp/worker2.log 2>&1 & w2=$!
# Both workers registered before the job: a 64x48 frame can be done by the
# first before the second has said hello, and the listing below names both.
for _ in $(seq 100); do
  [ "$(locus workers --farm 127.0.0.1:7000 2>/dev/null | tail -n +2 | wc -l)" -ge 2 ] && break
  sleep 0.1
done
timeout 120 locus submit /tmp/spheres.json --farm 127.0.0.1:7000 --size 64x48 -o /tmp/farm/spheres.png --wait \
  >/tmp/submit.log 2>&1 || { echo "submit: failed"; exit 11; }
locus workers --farm 127.0.0.1:7000 >/tmp/workers.txt 2>&1
kill -TERM "$w1" "$w2"
wait "$w1"; echo "worker1 exit $?"
wait "$w2"; echo "worker2 exit $?"
t0=$(date +%s%N)
kill -TERM "$cpid"
wait "$cpid"; rc=$?
echo "coordinator exit $rc after $((($(date +%s%N) - t0) / 1000000)) ms"
timeout 120 locus render /tmp/spheres.json --size 64x48 --workers 2 -o /tmp/embedded.png >/tmp/embedded.log 2>&1
echo "embedded exit $?"
EOF
} >"$root/tmp/services.sh"
unshare --net --mount --pid --fork --mount-proc="$root/proc" bash -c '
  ip link set lo up || exit 12
  exec chroot "$1" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root LANG=C.UTF-8 bash /tmp/services.sh
' - "$root" >"$tmp/services.out" 2>&1
rc=$?
sed 's/^/  | /' "$tmp/services.out"
if [ $rc -ne 0 ]; then
  bad "the services did not run (status $rc)"
  for f in coordinator worker1 worker2 submit; do echo "  --- $f.log"; tail -15 "$root/tmp/$f.log" 2>/dev/null; done
else
  same_image "$tmp/host.png" "$root/tmp/farm/spheres.png" &&
    ok "coordinator and locus-worker@1, @2 as configured: the job's frame == the render" ||
    { bad "the farm's frame differs"; tail -5 "$root/tmp/submit.log"; }
  short=$(hostname -s)
  grep -q "$short-1" "$root/tmp/workers.txt" && grep -q "$short-2" "$root/tmp/workers.txt" &&
    ok "locus workers lists $short-1 and $short-2 (--name %l-%i)" ||
    { bad "worker names"; cat "$root/tmp/workers.txt"; }
  grep -q "^worker1 exit 0$" "$tmp/services.out" && grep -q "^worker2 exit 0$" "$tmp/services.out" &&
    ok "workers exit 0 on SIGTERM" || bad "workers' exit on SIGTERM"
  ms=$(sed -n 's/^coordinator exit 0 after \([0-9]*\) ms$/\1/p' "$tmp/services.out")
  [ -n "$ms" ] && [ "$ms" -lt $((${stop_timeout:-0} * 1000)) ] &&
    ok "SIGTERM: the coordinator drains and exits 0 in $ms ms (TimeoutStopSec=$stop_timeout)" ||
    { bad "the coordinator's stop (TimeoutStopSec=$stop_timeout)"; tail -10 "$root/tmp/coordinator.log"; }
  [ "$(in_root stat -c %U /var/lib/locus/locus.db 2>/dev/null)" = locus ] &&
    ok "its job store /var/lib/locus/locus.db, owned by locus" || bad "no job store in /var/lib/locus"
  grep -q "^embedded exit 0$" "$tmp/services.out" && same_image "$tmp/host.png" "$root/tmp/embedded.png" &&
    ok "/usr/bin/locus render --workers 2 (embedded farm, /usr/bin/locus-worker) == the render" ||
    { bad "the embedded farm in the root"; tail -10 "$root/tmp/embedded.log"; }
fi

# ---- 5. the units, checked by systemd
step "systemd-analyze verify and security (systemd installed in the root)"
in_root apt-get -q -y -o APT::Sandbox::User=root install systemd >>"$tmp/apt.log" 2>&1 ||
  { tail -20 "$tmp/apt.log"; die "apt-get install systemd in the root"; }
MANPATH=$root/usr/share/man systemd-analyze verify --root="$root" \
  locus-coordinator.service locus-worker@1.service >"$tmp/verify.log" 2>&1
rc=$?
[ $rc -eq 0 ] && [ ! -s "$tmp/verify.log" ] && ok "systemd-analyze verify: clean (binaries, man pages, every key)" ||
  { bad "systemd-analyze verify (status $rc)"; cat "$tmp/verify.log"; }
for unit in locus-coordinator.service locus-worker@1.service; do
  if systemd-analyze security --offline=true --root="$root" --threshold=20 "$unit" >"$tmp/security.log" 2>&1; then
    ok "$(grep -o 'Overall exposure level.*' "$tmp/security.log")"
  else
    bad "exposure above 2.0: $(grep -o 'Overall exposure level.*' "$tmp/security.log")"
    grep "✗" "$tmp/security.log"
  fi
done
drain_ms=$(grep '^LOCUS_COORDINATOR_ARGS=' "$root/etc/locus/coordinator.conf" | grep -o -- '--drain-ms[= ][0-9]*' | grep -o '[0-9]*$')
[[ $stop_timeout =~ ^[0-9]+$ ]] && [ "$(unit_key locus-coordinator.service KillSignal)" = SIGTERM ] &&
  [ $((${drain_ms:-20000} + 5000)) -le $((stop_timeout * 1000)) ] &&
  ok "KillSignal=SIGTERM; --drain-ms ${drain_ms:-20000 (default)} + 5 s <= TimeoutStopSec=$stop_timeout" ||
  bad "--drain-ms ${drain_ms:-default} does not fit in TimeoutStopSec=$stop_timeout"

# ---- 6. reinstall and purge
step "reinstall keeps an edited conffile; purge"
echo "# edited by the package test" >>"$root/etc/locus/worker.conf"
in_root dpkg -i "/tmp/$(basename "$deb")" >"$tmp/dpkg.log" 2>&1 &&
  grep -q "edited by the package test" "$root/etc/locus/worker.conf" &&
  ok "reinstalled over itself; the edited worker.conf kept" || { bad "reinstall"; tail -10 "$tmp/dpkg.log"; }
in_root apt-get -q -y purge locus >>"$tmp/dpkg.log" 2>&1 || { bad "apt-get purge locus"; tail -10 "$tmp/dpkg.log"; }
[ ! -e "$root/usr/bin/locus-coordinator" ] && [ ! -e "$units/locus-worker@.service" ] && [ ! -e "$root/etc/locus" ] &&
  ok "purged: binaries, units and /etc/locus gone" || bad "files left after purge"
in_root getent passwd locus >/dev/null && [ -f "$root/var/lib/locus/locus.db" ] &&
  ok "purged: the user locus and the job store kept" || bad "purge removed the user or /var/lib/locus"

step "done: $fails failure(s)"
[ $fails -eq 0 ]
