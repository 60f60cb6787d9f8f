#!/usr/bin/env bash
# The Debian packages from the build (ctest deb_package, docs/install.md): `cpack -G DEB` in the
# build folder, what dpkg-deb says about each package (control fields, maintainer scripts,
# conffiles, the files that must be there), then the stepcal package unpacked with `dpkg -x` into
# a temporary root and its stepcal-runtime and stepcal-client run from there against a model,
# over real UDP multicast in a private network namespace (tests/system/in_netns.sh). Nothing is
# installed on the host.
#
# Usage: tests/system/deb_package.sh BUILD_DIR MODEL CAMPAIGN_DIR WORK_DIR
# Exit status 77 (skipped) after the package checks when the machine permits no network namespace.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
build=$(realpath "$1") model=$(realpath "$2") campaign=$(realpath "$3") work=$4
rm -rf "$work"
mkdir -p "$work"
work=$(realpath "$work")

(cd "$build" && cpack -G DEB -B "$work/packages" >"$work/cpack.log") ||
  { cat "$work/cpack.log" >&2; exit 1; }
fail() { echo "deb_package: $*" >&2; exit 1; }
shopt -s nullglob
debs=("$work"/packages/*.deb)
echo "built: $(cd "$work/packages" && ls -- *.deb | tr '\n' ' ')"
for name in stepcal stepcal-dev; do
  [[ -f $(echo "$work"/packages/"$name"_*.deb) ]] || fail "no ${name}_*.deb among ${debs[*]}"
done
deb=$(echo "$work"/packages/stepcal_*.deb)
dev=$(echo "$work"/packages/stepcal-dev_*.deb)

# Control fields: dependencies from the executables' shared libraries and the system user's tool.
info=$(dpkg-deb --info "$deb")
depends=$(dpkg-deb --field "$deb" Depends)
echo "stepcal Depends: $depends"
for dependency in adduser liblcm1 libyaml-cpp libc6; do
  grep -q "$dependency" <<<"$depends" || fail "stepcal: no $dependency in Depends"
done
for script in postinst prerm postrm conffiles; do
  grep -q " $script" <<<"$info" || fail "stepcal: no $script in the control archive"
done
dpkg-deb --ctrl-tarfile "$deb" | tar -xO ./conffiles | grep -qx /etc/stepcal/cell1.conf ||
  fail "stepcal: /etc/stepcal/cell1.conf is not a conffile"
dev_depends=$(dpkg-deb --field "$dev" Depends)
echo "stepcal-dev Depends: $dev_depends"
for dependency in libeigen3-dev liblcm-dev; do
  grep -q "$dependency" <<<"$dev_depends" || fail "stepcal-dev: no $dependency in Depends"
done

# Contents.
contents=$(dpkg-deb --contents "$deb" | awk '{ print $6 }')
for path in ./usr/bin/stepcal ./usr/bin/stepcal-runtime ./usr/bin/stepcal-client \
            ./lib/systemd/system/stepcal-runtime@.service ./etc/stepcal/cell1.conf \
            ./var/lib/stepcal/ ./usr/share/stepcal/robots/ur10.urdf ./usr/share/doc/stepcal/docs/install.md \
            ./usr/share/doc/stepcal/docs/img/plan-compare.png ./usr/share/doc/stepcal/copyright; do
  grep -qxF "$path" <<<"$contents" || fail "stepcal: $path missing"
done
dev_contents=$(dpkg-deb --contents "$dev" | awk '{ print $6 }')
for pattern in 'libstepcal_runtime\.a$' 'cmake/stepcal/stepcalConfig\.cmake$' \
               'pkgconfig/stepcal-runtime\.pc$' 'include/stepcal/runtime/corrector\.hpp$' \
               'include/stepcal_lcm/correction_request_t\.hpp$' 'share/stepcal/lcmtypes/correction_request_t\.lcm$'; do
  grep -qE "$pattern" <<<"$dev_contents" || fail "stepcal-dev: nothing matches $pattern"
done
# Nothing of the build or source tree leaks into the packages.
if dpkg-deb --contents "$deb" | grep -F -e "$build" -e "$root"; then fail "build paths packaged"; fi
unit=$(dpkg-deb --fsys-tarfile "$deb" | tar -xO ./lib/systemd/system/stepcal-runtime@.service)
grep -qx 'ExecStart=/usr/bin/stepcal-runtime --config /etc/stepcal/%i.conf' <<<"$unit" ||
  fail "the unit's ExecStart is not the installed daemon's"
grep -qx 'LoadCredential=cell-key:/etc/stepcal/%i.key' <<<"$unit" ||
  fail "the unit does not hand /etc/stepcal/%i.key over as the credential cell-key"
grep -qx 'SetCredential=cell-key:none' <<<"$unit" || fail "the unit has no fallback for a cell without a key"
echo "package checks: passed"

# Unpacked, not installed: the daemon and the client from the temporary root.
dpkg -x "$deb" "$work/root"
read -r -a row < <("$root/tests/system/campaign_row.sh" "$campaign")
# The client takes joints in degrees (the row's are in rad, for the C++ consumer).
q_deg=()
for q in "${row[@]:0:6}"; do q_deg+=("$(awk -v q="$q" 'BEGIN { printf "%.17g", q * 180 / 3.141592653589793 }')"); done
bin=$work/root/usr/bin
set +e
"$root/tests/system/in_netns.sh" bash -c '
  set -euo pipefail
  bin=$1 conf=$2 model=$3 log=$4
  shift 4
  "$bin/stepcal-runtime" --config "$conf" --model "$model" 2>"$log" &
  daemon=$!
  for _ in $(seq 100); do grep -q "serving" "$log" && break; sleep 0.1; done
  "$bin/stepcal-client" --forward "${@:1:6}" --wrench "${@:7:6}" --timeout-ms 2000 --json >"$log.reply"
  kill -TERM $daemon
  wait $daemon
  cat "$log"
' _ "$bin" "$work/root/etc/stepcal/cell1.conf" "$model" "$work/daemon.log" "${q_deg[@]}" "${row[@]:6}"
status=$?
set -e
[[ $status -eq 77 ]] && { echo "deb_package: daemon run skipped (no network namespace)"; exit 77; }
[[ $status -eq 0 ]] || { cat "$work/daemon.log" >&2; fail "the unpacked daemon and client failed"; }
jq -e --argjson x "${row[12]}" --argjson y "${row[13]}" --argjson z "${row[14]}" \
  '.status == "OK" and ((.predicted_position_m[0] - $x) * (.predicted_position_m[0] - $x) +
    (.predicted_position_m[1] - $y) * (.predicted_position_m[1] - $y) +
    (.predicted_position_m[2] - $z) * (.predicted_position_m[2] - $z)) < 0.5e-3 * 0.5e-3' \
  "$work/daemon.log.reply" >/dev/null || { cat "$work/daemon.log.reply" >&2; fail "unexpected reply"; }
echo "unpacked stepcal-runtime answered stepcal-client: OK, within 0.5 mm of the measured position"

# The cell key as stepcal-runtime@.service hands it over (LoadCredential=cell-key:/etc/stepcal/
# %i.key): the file root:root 0600, systemd's copy in a fresh folder only the service user may
# read, CREDENTIALS_DIRECTORY naming it, the daemon run as that user. No systemd runs here, so
# this does what it does; the user `stepcal` (the package's postinst makes it) exists only in a
# private mount namespace (passwd and group bind-mounted), nothing changes on the host.
key=$work/root/etc/stepcal/cell1.key
head -c 32 /dev/urandom >"$key"
chown root:root "$key"
chmod 600 "$key"
set +e
"$root/tests/system/in_netns.sh" unshare -m --propagation private bash -c '
  set -euo pipefail
  bin=$1 conf=$2 model=$3 key=$4 work=$5
  shift 5
  uid=$(awk -F: "\$3 >= 60000 && \$3 < 65000 { used[\$3] } END { for (u = 64000; u in used; ++u); print u }" /etc/passwd)
  cp /etc/passwd "$work/passwd"
  cp /etc/group "$work/group"
  echo "stepcal:x:$uid:$uid:stepcal runtime daemon:/var/lib/stepcal:/usr/sbin/nologin" >>"$work/passwd"
  echo "stepcal:x:$uid:" >>"$work/group"
  mount --bind "$work/passwd" /etc/passwd
  mount --bind "$work/group" /etc/group
  as_stepcal=(setpriv --reuid=stepcal --regid=stepcal --clear-groups)

  # Read directly as stepcal: refused with one line naming the file, the user and the fix.
  if "${as_stepcal[@]}" "$bin/stepcal-runtime" --config "$conf" --model "$model" --key-file "$key" \
       2>"$work/denied.log"; then
    echo "the daemon read a root-owned 0600 key as stepcal" >&2; exit 1
  fi
  cat "$work/denied.log"
  grep -qF "stepcal-runtime: error: $key: --key-file: permission denied: user stepcal may not read the cell key (owner root); keep it root:root 0600 and let systemd hand it to the daemon as the credential cell-key (LoadCredential=cell-key:" "$work/denied.log"
  [[ $(wc -l <"$work/denied.log") -eq 1 ]]

  # Handed over as systemd does: a copy mode 0400 owned by the user, in a folder only it reads.
  credentials=$work/credentials
  mkdir -m 0500 "$credentials"
  install -m 0400 -o stepcal -g stepcal "$key" "$credentials/cell-key"
  chown stepcal:stepcal "$credentials"
  CREDENTIALS_DIRECTORY=$credentials "${as_stepcal[@]}" "$bin/stepcal-runtime" --config "$conf" \
    --model "$model" 2>"$work/keyed.log" &
  daemon=$!
  for _ in $(seq 100); do grep -q "serving" "$work/keyed.log" && break; sleep 0.1; done
  grep -qF "cell key $credentials/cell-key (credential cell-key; requests, replies and sensor commands authenticated)" "$work/keyed.log"
  # Without the key the client is told the key is missing (exit 4); with it, answered.
  set +e
  "$bin/stepcal-client" --forward "${@:1:6}" --wrench "${@:7:6}" --timeout-ms 500 2>"$work/unkeyed.err"
  unkeyed=$?
  set -e
  cat "$work/unkeyed.err"
  [[ $unkeyed -eq 4 ]]
  grep -qF "the key is missing; give the cell'"'"'s key with --key-file" "$work/unkeyed.err"
  "$bin/stepcal-client" --forward "${@:1:6}" --wrench "${@:7:6}" --timeout-ms 2000 --key-file "$key" \
    --json >"$work/keyed.reply"
  kill -TERM $daemon
  wait $daemon
  [[ $(stat -c %U:%G:%a "$key") == root:root:600 ]]
' _ "$bin" "$work/root/etc/stepcal/cell1.conf" "$model" "$key" "$work" "${row[@]}"
status=$?
set -e
[[ $status -eq 0 ]] || { cat "$work/keyed.log" >&2; fail "the keyed daemon as user stepcal failed"; }
jq -e '.status == "OK"' "$work/keyed.reply" >/dev/null || { cat "$work/keyed.reply" >&2; fail "unexpected keyed reply"; }
echo "as user stepcal: the root-owned 0600 key refused when read directly (one line), taken as the credential cell-key; a client without it told the key is missing (exit 4), one with it answered OK"
