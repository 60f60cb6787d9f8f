#!/bin/sh
# /init of the small CAN VM that tests/system/vcan_run.sh boots (busybox ash, PID 1, no udev, no systemd).
#
# tests/system/vcan_run.sh copies this file into the cached initramfs next to a static busybox and the
# kernel modules listed in /lib/vcan/modules.list (dependency order, already decompressed). It
# then boots the VM with three kinds of 9p shares:
#   hostroot  the host's / (read-only)            -> /host, the chroot the command runs in
#   vcanrun   the per-run temp dir (read-write)   -> /run/vcan here and, inside the chroot, at its
#                                                    host path, so run.sh and status are found
#   w1 w2 ..  the --writable dirs (read-write)    -> at their host paths inside the chroot
# and two virtio-serial ports named stdout and stderr that the host joins to its own stdout and
# stderr. The kernel console (ttyS0) goes to a log file on the host, never to the caller's
# output; so does everything this script prints, and the host shows its tail only when the VM
# fails.
#
# Files in the run dir, written by the host: run.sh (bash script: cd, exports, exec of the
# command: written by the host's bash with printf %q, run by the host's bash in the chroot so the
# quoting always matches), hostpath (the run dir's path on the host), writable (lines "TAG PATH").
# Written here: status (the command's exit status) or error (one line: why setup failed).

PATH=/bin:/sbin:/usr/bin:/usr/sbin
export PATH
RUN=/run/vcan
NINEP_OPTS=trans=virtio,version=9p2000.L,msize=512000

# Milestones with the guest uptime, in the console log (for docs/vcan.md's timings and failures).
stage() { echo "vcan-vm: $* at $(cut -d' ' -f1 /proc/uptime)s" >&2; }

fail() {
  echo "vcan-vm: $*" >&2
  # The host turns this file into its one-line error; without it, it shows the console log.
  if [ -d "$RUN" ] && [ -w "$RUN" ]; then echo "$*" >"$RUN/error"; fi
  sync
  poweroff -f
  exit 1
}

# The initramfs has only /bin/sh -> busybox: make the other applet links now.
/bin/busybox mkdir -p /proc /sys /dev /tmp /run /usr/bin /usr/sbin /sbin /host
/bin/busybox --install -s
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev 2>/dev/null || true
stage "init started"

# The modules are listed in dependency order by the host (modinfo depends), so plain insmod is
# enough and no modules.dep is needed here.
while IFS= read -r mod; do
  [ -n "$mod" ] || continue
  insmod "/lib/vcan/modules/$mod" || fail "insmod $mod failed (kernel $(uname -r))"
done </lib/vcan/modules.list

stage "modules loaded"
mkdir -p "$RUN"
mount -t 9p -o "$NINEP_OPTS" vcanrun "$RUN" || fail "cannot mount the run dir (9p tag vcanrun)"
hostpath=$(cat "$RUN/hostpath") || fail "no hostpath file in the run dir"

# The host's / read-only. cache=loose: binaries and libraries are read again and again and do
# not change during one run; exec got ~1.3x faster (20 x /bin/true: 0.8-1.0 s instead of 1.0-1.3).
mount -t 9p -o "$NINEP_OPTS,ro,cache=loose" hostroot /host || fail "cannot mount the host's / over 9p"
[ -x /host/bin/bash ] || fail "the host has no /bin/bash (needed to run the command)"

# What a program expects to find writable or live inside the chroot.
mount -t proc proc /host/proc || fail "mount /host/proc"
mount -t sysfs sysfs /host/sys || fail "mount /host/sys"
mount -t devtmpfs devtmpfs /host/dev || fail "mount /host/dev"
mkdir -p /host/dev/pts /host/dev/shm
mount -t devpts -o newinstance,ptmxmode=0666 devpts /host/dev/pts 2>/dev/null || true
mount -t tmpfs -o mode=1777 tmpfs /host/dev/shm || fail "mount /host/dev/shm"
mount -t tmpfs -o mode=0755 tmpfs /host/run || fail "mount /host/run"
# /tmp and /var/tmp: an overlay (host content read-only below, guest tmpfs above), so a command
# or a run dir that lives in the host's /tmp is still visible; plain tmpfs if overlay fails.
mkdir -p /ovl
mount -t tmpfs tmpfs /ovl || fail "mount tmpfs for overlays"
for d in tmp var/tmp; do
  [ -d "/host/$d" ] || continue
  n=$(echo "$d" | tr / _)
  mkdir -p "/ovl/$n/upper" "/ovl/$n/work"
  chmod 1777 "/ovl/$n/upper"
  mount -t overlay overlay -o "lowerdir=/host/$d,upperdir=/ovl/$n/upper,workdir=/ovl/$n/work" "/host/$d" 2>/dev/null ||
    mount -t tmpfs -o mode=1777 tmpfs "/host/$d" || fail "mount /host/$d"
done

# The run dir at its host path (after /tmp, which it is usually under), then the --writable dirs.
# A path hidden by the tmpfs above (TMPDIR=/run/...) gets its mount point made there.
[ -d "/host$hostpath" ] || mkdir -p "/host$hostpath" 2>/dev/null ||
  fail "run dir $hostpath not visible in the guest"
mount -o bind "$RUN" "/host$hostpath" || fail "bind-mount the run dir at $hostpath"
if [ -s "$RUN/writable" ]; then
  while IFS= read -r line; do
    tag=${line%% *}
    path=${line#* }
    [ -d "/host$path" ] || mkdir -p "/host$path" 2>/dev/null ||
      fail "--writable $path: not a directory seen from the guest"
    mount -t 9p -o "$NINEP_OPTS" "$tag" "/host$path" || fail "mount --writable $path (9p tag $tag)"
  done <"$RUN/writable"
fi

# Loopback with multicast: LCM's udpm:// (ttl=0) sends to 239.255.76.67 and must loop back on lo.
ip link set lo up || fail "ip link set lo up"
ip link set lo multicast on 2>/dev/null || chroot /host ip link set lo multicast on ||
  fail "ip link set lo multicast on"
ip route add 224.0.0.0/4 dev lo || fail "ip route add 224.0.0.0/4 dev lo"

# vcan0: busybox ip passes "type vcan" as the link kind; the host's iproute2 (run in the chroot)
# is the fallback should a busybox build not.
if ! ip link add dev vcan0 type vcan 2>/dev/null; then
  chroot /host ip link add dev vcan0 type vcan || fail "cannot create vcan0 (busybox ip and host ip failed)"
fi
ip link set vcan0 up || fail "ip link set vcan0 up"

# The virtio-serial ports by name (no udev here, so no /dev/virtio-ports links).
out=
err=
for p in /sys/class/virtio-ports/*; do
  [ -r "$p/name" ] || continue
  case $(cat "$p/name") in
    stdout) out=/dev/${p##*/} ;;
    stderr) err=/dev/${p##*/} ;;
  esac
done
if [ -z "$out" ] || [ -z "$err" ]; then fail "virtio-serial ports stdout/stderr not found"; fi

stage "running the command"
# The command: the host's bash runs run.sh (cd + exports + exec) in the chroot, stdin empty,
# environment only what run.sh exports (env -i: nothing of this init's or the kernel's).
env -i chroot /host /bin/bash "$hostpath/run.sh" </dev/null >"$out" 2>"$err"
status=$?
stage "command exited with $status"
echo "$status" >"$RUN/status.tmp" && mv "$RUN/status.tmp" "$RUN/status"
sync
poweroff -f
