#!/usr/bin/env bash
# tests/package/check-package.sh [BUILD_DIR]: the Debian package on a fresh Debian 12.
#
# Builds inertia_<version>_amd64.deb from BUILD_DIR (default: build), installs it with apt into a
# minimal Debian 12 root made by debootstrap, and checks, in that root:
#   - the package's files, its conffile, and that its dependencies are runtime packages only;
#   - apt pulls what the binaries need (nothing unresolved in ldd);
#   - the inertia user and the inertia-operators group (sysusers.d) and /var/lib/inertia
#     (tmpfiles.d) exist;
#   - systemd-analyze verify passes on the installed unit, and
#     systemd-analyze security --offline=yes gives an exposure of at most 1.8;
#   - the installed daemon runs a simulated bench as user inertia and writes its log there
#     (a chroot has no systemd as PID 1: setpriv starts it as the service would, by user);
#   - inertia-daqd --check on the installed /etc/inertia/bench.toml names what is missing, exit 2;
#   - an upgrade keeps an edited /etc/inertia/bench.toml; remove keeps config and logs; purge
#     removes the config and keeps the logs.
# Exit 0 when every check passes, 1 when one fails, 77 when a prerequisite is missing (not root,
# no debootstrap, Debian's mirror out of reach): .ci/run then reports it skipped.
#
# The debootstrapped root is cached as a tarball (INERTIA_PACKAGE_CACHE, default
# /var/cache/inertia-package-test) with the .debs apt downloads, so a second run needs no
# network for packages it has seen. INERTIA_DEBIAN_MIRROR overrides http://deb.debian.org/debian.
# KEEP_ROOT=1 leaves the root in place for a look (its path is printed).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
build_dir="$(cd "${1:-$here/build}" && pwd)"
mirror="${INERTIA_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
cache="${INERTIA_PACKAGE_CACHE:-/var/cache/inertia-package-test}"
suite=bookworm

t_start=$(date +%s)
stage_start=$t_start
stage() {  # prints the previous stage's time, then the new stage's name
  local now
  now=$(date +%s)
  [ -n "${stage_name:-}" ] && printf 'package-test: %-34s %4d s\n' "$stage_name" $((now - stage_start))
  stage_name="$1"
  stage_start=$now
}
skip() { echo "package-test: SKIP: $*" >&2; exit 77; }
fail() { echo "package-test: FAIL: $*" >&2; exit 1; }
pass() { echo "package-test: ok: $*"; }

[ "$(id -u)" -eq 0 ] || skip "needs root (debootstrap, chroot, mount)"
command -v debootstrap >/dev/null || skip "debootstrap is not installed (apt-get install debootstrap)"
command -v dpkg-deb >/dev/null || skip "dpkg-deb is not installed"
[ -f "$build_dir/CPackConfig.cmake" ] || fail "$build_dir is not a configured build directory (no CPackConfig.cmake)"

work="$(mktemp -d /var/tmp/inertia-package-test.XXXXXX)"
root="$work/root"
mounted=()
cleanup() {
  local i
  for ((i = ${#mounted[@]} - 1; i >= 0; i--)); do umount -l "${mounted[i]}" 2>/dev/null || true; done
  if [ "${KEEP_ROOT:-0}" = 1 ]; then echo "package-test: root kept in $root" >&2; else rm -rf "$work"; fi
}
trap cleanup EXIT
in_root() { chroot "$root" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin LANG=C.UTF-8 "$@"; }

# ---- the package ----------------------------------------------------------------------------
stage "build the package (cpack)"
# The package target reconfigures when a CMake file changed and builds what is missing first.
rm -f "$build_dir"/inertia_*_amd64.deb
nice -n 10 cmake --build "$build_dir" --target package >"$work/cpack.log" 2>&1 ||
  { cat "$work/cpack.log" >&2; fail "cmake --build $build_dir --target package"; }
deb="$(ls "$build_dir"/inertia_*_amd64.deb)"
version="$(dpkg-deb -f "$deb" Version)"
depends="$(dpkg-deb -f "$deb" Depends)"
recommends="$(dpkg-deb -f "$deb" Recommends)"
echo "package-test: $(basename "$deb"): $(du -k "$deb" | cut -f1) KiB, installed $(dpkg-deb -f "$deb" Installed-Size) KiB"
echo "package-test: Depends: $depends"
echo "package-test: Recommends: $recommends"
if echo "$depends" | tr ',' '\n' | grep -Eq -- '-dev( |$)'; then fail "a development package among the Depends: $depends"; fi
for lib in libmodbus5 libgpiod2 liblcm1 libsystemd0 libssl3 libstdc++6 libc6 systemd procps; do
  case "$depends" in *"$lib"*) ;; *) fail "Depends lacks $lib: $depends" ;; esac
done
dpkg-deb -c "$deb" | awk '{print $6}' >"$work/contents"
for f in ./usr/bin/inertia-daqd ./usr/bin/inertia-analyze ./usr/lib/systemd/system/inertia-daqd.service \
  ./usr/lib/sysusers.d/inertia.conf ./usr/lib/tmpfiles.d/inertia.conf ./etc/inertia/bench.toml \
  ./usr/share/inertia/config/bench-template.toml ./usr/share/inertia/config/sim-paper-daq.toml \
  ./usr/share/inertia/inertia-lcm-spy ./usr/share/inertia/inertia_lcm_types.jar ./usr/share/doc/inertia/README.md \
  ./usr/share/doc/inertia/docs/design.md ./usr/share/doc/inertia/docs/test-executive.md \
  ./usr/share/doc/inertia/copyright ./usr/share/man/man1/inertia-daqd.1.gz ./usr/share/man/man1/inertia-analyze.1.gz; do
  grep -qx "$f" "$work/contents" || fail "the package lacks $f"
done
[ "$(dpkg-deb -I "$deb" conffiles)" = /etc/inertia/bench.toml ] || fail "conffiles is not exactly /etc/inertia/bench.toml"
pass "package $version: files, conffile and dependencies"

# ---- a fresh Debian 12 root -----------------------------------------------------------------
stage "debootstrap (or its cached tarball)"
mkdir -p "$cache/archives/partial"
base="$cache/$suite-minbase.tar"
mkdir -p "$root"
if [ -f "$base" ]; then
  tar -C "$root" -xf "$base"
else
  curl -fsS --max-time 20 -o /dev/null "$mirror/dists/$suite/Release" 2>/dev/null ||
    wget -q -T 20 -O /dev/null "$mirror/dists/$suite/Release" 2>/dev/null ||
    skip "Debian's mirror $mirror is out of reach"
  debootstrap --variant=minbase --cache-dir="$cache/archives" "$suite" "$root" "$mirror" >"$work/debootstrap.log" 2>&1 ||
    { tail -20 "$work/debootstrap.log" >&2; fail "debootstrap"; }
  cat >"$root/etc/apt/sources.list" <<EOF
deb $mirror $suite main
deb $mirror $suite-updates main
deb http://deb.debian.org/debian-security $suite-security main
EOF
  tar -C "$root" -cf "$base.tmp" . && mv "$base.tmp" "$base"
fi
cp /etc/resolv.conf "$root/etc/resolv.conf"
mount -t proc proc "$root/proc" && mounted+=("$root/proc")
mount --bind /dev "$root/dev" && mounted+=("$root/dev")
# apt's downloads survive the root: the next run installs from them.
mount --bind "$cache/archives" "$root/var/cache/apt/archives" && mounted+=("$root/var/cache/apt/archives")
echo 'Binary::apt::APT::Keep-Downloaded-Packages "true";' >"$root/etc/apt/apt.conf.d/99keep-downloads"

stage "apt install ./$(basename "$deb")"
cp "$deb" "$root/tmp/"
install_deb() {
  in_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "/tmp/$1" >"$work/apt.log" 2>&1
}
in_root apt-get update -q >"$work/apt-update.log" 2>&1 || { cat "$work/apt-update.log" >&2; fail "apt-get update in the root"; }
install_deb "$(basename "$deb")" || { tail -30 "$work/apt.log" >&2; fail "apt-get install ./$(basename "$deb")"; }
grep -E "^(Get|Setting up)" "$work/apt.log" | sed -n 's/^Setting up \([^ ]*\).*/\1/p' | tr '\n' ' ' >"$work/installed"
echo "package-test: apt set up $(wc -w <"$work/installed") packages: $(cat "$work/installed")"
for bin in /usr/bin/inertia-daqd /usr/bin/inertia-analyze; do
  ! in_root ldd "$bin" | grep -q "not found" || { in_root ldd "$bin" >&2; fail "$bin has unresolved libraries"; }
done
in_root /usr/bin/inertia-daqd --help >/dev/null || fail "inertia-daqd --help"
in_root /usr/bin/inertia-analyze --help >/dev/null || fail "inertia-analyze --help"
pass "apt pulled every runtime dependency (ldd resolves both binaries)"

stage "user, state directory, unit"
in_root id inertia >/dev/null || fail "no user inertia"
in_root getent group inertia-operators >/dev/null || fail "no group inertia-operators (who may command the bench)"
echo "package-test: $(in_root id inertia)"
[ "$(in_root stat -c '%U:%G %a' /var/lib/inertia)" = "inertia:inertia 750" ] ||
  fail "/var/lib/inertia is $(in_root stat -c '%U:%G %a' /var/lib/inertia), not inertia:inertia 750"
in_root systemd-analyze verify /usr/lib/systemd/system/inertia-daqd.service >"$work/verify.log" 2>&1 ||
  { cat "$work/verify.log" >&2; fail "systemd-analyze verify"; }
pass "systemd-analyze verify inertia-daqd.service"
in_root systemd-analyze security --offline=yes /usr/lib/systemd/system/inertia-daqd.service >"$work/security.log" 2>&1 || true
exposure="$(sed -n 's/.*Overall exposure level for inertia-daqd.service: \([0-9.]*\).*/\1/p' "$work/security.log")"
[ -n "$exposure" ] || { cat "$work/security.log" >&2; fail "systemd-analyze security printed no exposure"; }
awk -v e="$exposure" 'BEGIN { exit !(e <= 1.8) }' || { grep '✗' "$work/security.log" >&2; fail "exposure $exposure > 1.8"; }
pass "systemd-analyze security --offline=yes: exposure $exposure (<= 1.8)"

stage "the daemon as user inertia"
# As the unit runs it: user inertia, its groups, the state directory; memq:// keeps LCM in the
# process (the root shares this machine's network, which may have no multicast route).
in_root setpriv --reuid=inertia --regid=inertia --init-groups -- \
  /usr/bin/inertia-daqd --config /usr/share/inertia/config/sim-paper-daq.toml --log /var/lib/inertia/log \
  --fast --duration 2 --lcm-url memq:// >"$work/daqd.log" 2>&1 || { cat "$work/daqd.log" >&2; fail "inertia-daqd as inertia"; }
logs="$(in_root find /var/lib/inertia/log -name '*.lcmlog' -user inertia -size +1k | wc -l)"
[ "$logs" -ge 1 ] || { in_root ls -laR /var/lib/inertia >&2; fail "no event log owned by inertia in /var/lib/inertia/log"; }
echo "package-test: $(grep -E '^  (run|log):' "$work/daqd.log" | tr -s ' ' | tr '\n' ';')"
pass "the installed daemon ran sim-paper-daq.toml as inertia and wrote $logs log file(s) in /var/lib/inertia/log"
rc=0
in_root setpriv --reuid=inertia --regid=inertia --init-groups -- \
  /usr/bin/inertia-daqd --check --config /etc/inertia/bench.toml >"$work/check.log" 2>&1 || rc=$?
[ "$rc" -eq 2 ] || { cat "$work/check.log" >&2; fail "--check on the template: exit $rc, not 2"; }
grep -q "at /etc/inertia/bench.toml:" "$work/check.log" || { cat "$work/check.log" >&2; fail "--check names no line"; }
pass "inertia-daqd --check on the template bench: exit 2, $(grep -c FAIL "$work/check.log") failures named with their line"

stage "upgrade, remove, purge"
echo "# edited on this bench" >>"$root/etc/inertia/bench.toml"
repack="$work/repack"
dpkg-deb -R "$deb" "$repack"
sed -i "s/^Version: .*/Version: $version+upgrade/" "$repack/DEBIAN/control"
dpkg-deb -b "$repack" "$root/tmp/inertia_upgrade_amd64.deb" >/dev/null
install_deb inertia_upgrade_amd64.deb || { tail -30 "$work/apt.log" >&2; fail "upgrade"; }
[ "$(in_root dpkg-query -W -f '${Version}' inertia)" = "$version+upgrade" ] || fail "upgrade did not happen"
tail -n 1 "$root/etc/inertia/bench.toml" | grep -q "edited on this bench" || fail "the upgrade overwrote /etc/inertia/bench.toml"
pass "upgrade kept the edited /etc/inertia/bench.toml"
in_root env DEBIAN_FRONTEND=noninteractive apt-get remove -y -q inertia >"$work/remove.log" 2>&1 || fail "apt-get remove"
[ ! -e "$root/usr/bin/inertia-daqd" ] || fail "remove left /usr/bin/inertia-daqd"
[ -f "$root/etc/inertia/bench.toml" ] || fail "remove deleted /etc/inertia/bench.toml"
[ "$(in_root find /var/lib/inertia/log -name '*.lcmlog' | wc -l)" -ge 1 ] || fail "remove deleted the logs"
pass "remove kept the config and the logs"
in_root env DEBIAN_FRONTEND=noninteractive apt-get purge -y -q inertia >"$work/purge.log" 2>&1 || fail "apt-get purge"
[ ! -e "$root/etc/inertia" ] || fail "purge left /etc/inertia"
[ "$(in_root find /var/lib/inertia/log -name '*.lcmlog' | wc -l)" -ge 1 ] || fail "purge deleted the logs"
pass "purge removed /etc/inertia and kept the logs"
stage ""
echo "package-test: all checks passed in $(($(date +%s) - t_start)) s"
