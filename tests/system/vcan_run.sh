#!/usr/bin/env bash
# Runs a command where SocketCAN works: directly on a host that has vcan0, otherwise inside a
# small qemu VM (TCG) whose Debian kernel has can, can-raw and vcan, with vcan0 up.
#
#   tests/system/vcan_run.sh [--timeout SECONDS] [--writable DIR]... [--] COMMAND [ARGS...]
#   tests/system/vcan_run.sh --prepare      # download + cache the VM kernel now (tools/setup.sh does)
#
# Exit status: COMMAND's; 124 on timeout (boot + command); 125 when the VM could not run it
# (the reason is the last line on stderr, "vcan_run: ..."). docs/vcan.md: the VM, timings.
#
# In the VM the command runs under chroot in the host's / (read-only over 9p), as root, in the
# caller's working directory, with stdin empty (on the host too), stdout and stderr on ours,
# and only these variables of the caller: PATH HOME LANG LC_ALL TZ USER and every STEPCAL_*,
# GTEST_*, LCM_*, plus STEPCAL_IN_VCAN_VM=1. /tmp, /var/tmp, /run, /dev/shm are writable there
# but thrown away; --writable DIR (repeatable, created if missing) shares DIR read-write at the
# same path so results survive.
#
# Environment:
#   STEPCAL_VCAN=auto|host|vm  auto (default): host if it has vcan0, else VM; host/vm: force one
#   STEPCAL_VM_CACHE           cache dir (default ${XDG_CACHE_HOME:-$HOME/.cache}/stepcal-vm)
#   STEPCAL_VM_CPUS, STEPCAL_VM_MEM_MB   guest size (default 2 CPUs, 2048 MiB)
#   STEPCAL_VM_TCG_THREAD=single|multi   qemu TCG threading (default single: see qemu_args)
#   STEPCAL_VM_KEEP=1          keep the per-run dir (console log, run.sh) and print its path
set -Eeuo pipefail
# A step failing under set -e would otherwise end the script without a word.
trap 'echo "vcan_run: internal error: \"$BASH_COMMAND\" failed (line $LINENO)" >&2' ERR

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd -P)
init_script=$here/vcan_vm_init.sh
cache=${STEPCAL_VM_CACHE:-${XDG_CACHE_HOME:-${HOME:-/tmp}/.cache}/stepcal-vm}
meta_pkg=linux-image-amd64
# Loaded in the guest with their dependencies (resolved here with modinfo): virtio_pci for the
# devices, 9pnet_virtio + 9p for the shares, virtio_console for the stdout/stderr ports.
modules_required=(virtio_pci 9pnet_virtio 9p virtio_console can can-raw vcan)
# Nice to have: overlay keeps the host's /tmp visible under a writable tmpfs; can-bcm for tests.
modules_optional=(overlay can-bcm)
# The variables that cross into the VM (prefixes end in _).
env_names=(PATH HOME LANG LC_ALL TZ USER)
env_prefixes=(STEPCAL_ GTEST_ LCM_)

die() { # die STATUS MESSAGE: the one line a caller (ctest log) needs to see what to do
  echo "vcan_run: $2" >&2
  exit "$1"
}

usage() {
  sed -n '2,/^set -E/{/^set -E/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
  exit "${1:-0}"
}

# ---------------------------------------------------------------------------- host SocketCAN
# True when vcan0 exists (or can be made) and is up here: then no VM is needed.
host_has_vcan() {
  command -v ip >/dev/null 2>&1 || return 1
  if ! ip link show dev vcan0 >/dev/null 2>&1; then
    ip link add dev vcan0 type vcan >/dev/null 2>&1 || return 1
  fi
  # Not root: "set up" is refused, but an interface someone else brought up is fine.
  ip link set dev vcan0 up >/dev/null 2>&1 || ip link show dev vcan0 | grep -q '[<,]UP[,>]'
}

# ---------------------------------------------------------------------------- VM kernel cache
# $cache/kernels/<package>_<version>/ holds vmlinuz, release, modules/*.ko (decompressed),
# modules.list (load order) and ready; $cache/current points at the one to boot. The initramfs
# (busybox + modules + tests/system/vcan_vm_init.sh) sits next to the kernel, keyed by a hash of what
# went in, so editing the init script rebuilds it without downloading anything.

lock_cache() { # serialize preparation between concurrent runs (ctest -j, two checkouts)
  mkdir -p "$cache"
  exec {lock_fd}>"$cache/.lock"
  flock "$lock_fd"
}

unlock_cache() {
  exec {lock_fd}>&-
}

# Sets kpkg and kver from apt's candidate of linux-image-amd64, a meta package whose Depends
# names the real one, usually with its exact version: "linux-image-6.1.0-56-amd64 (= 6.1.192-2)".
# (Each apt-cache call costs ~1 s here, hence one when that is enough.)
resolve_kernel_package() {
  local dep
  dep=$(apt-cache show --no-all-versions "$meta_pkg" 2>/dev/null |
    sed -n 's/^Depends:.*\(linux-image-[^ ,]*\( (= [^)]*)\)\{0,1\}\).*/\1/p' | head -n1) || return 1
  kpkg=${dep%% *}
  [[ -n $kpkg ]] || return 1
  kver=
  [[ $dep == *"(= "*")" ]] && kver=${dep#*(= } && kver=${kver%)}
  [[ -n $kver ]] ||
    kver=$(apt-cache show --no-all-versions "$kpkg" 2>/dev/null | sed -n 's/^Version: //p' | head -n1)
  [[ -n $kver ]]
}

decompress_module() { # SRC DEST: Debian ships .ko (bookworm) or .ko.xz / .ko.zst (later)
  case $1 in
    *.ko) cp "$1" "$2" ;;
    *.ko.xz)
      if command -v xz >/dev/null 2>&1; then xz -dc "$1" >"$2"; else busybox unxz -c "$1" >"$2"; fi ;;
    *.ko.zst)
      command -v zstd >/dev/null 2>&1 || die 125 "$1 is zstd-compressed: apt-get install zstd"
      zstd -qdc "$1" >"$2" ;;
    *.ko.gz) gzip -dc "$1" >"$2" ;;
    *) die 125 "unknown module format: $1" ;;
  esac
}

# Fills $dest/modules and $dest/modules.list from the unpacked package in $root.
collect_modules() {
  local root=$1 dest=$2 moddir f b
  # /lib/modules up to bookworm, /usr/lib/modules in later releases.
  moddir=$(find "$root/lib/modules" "$root/usr/lib/modules" -mindepth 1 -maxdepth 1 -type d \
    2>/dev/null | head -n1 || true)
  [[ -n $moddir ]] || die 125 "no lib/modules in the kernel package"
  basename "$moddir" >"$dest/release"
  declare -gA mod_path=() mod_builtin=() mod_seen=()
  mod_order=()
  while IFS= read -r -d '' f; do
    b=${f##*/}
    b=${b%%.ko*}
    mod_path[${b//-/_}]=$f
  done < <(find "$moddir" -name '*.ko*' -print0)
  if [[ -f $moddir/modules.builtin ]]; then
    while IFS= read -r f; do
      b=${f##*/}
      b=${b%%.ko*}
      mod_builtin[${b//-/_}]=1
    done <"$moddir/modules.builtin"
  fi
  mkdir -p "$dest/modules"
  for b in "${modules_required[@]}"; do add_module "$b" required "$dest"; done
  for b in "${modules_optional[@]}"; do add_module "$b" optional "$dest"; done
  printf '%s.ko\n' "${mod_order[@]}" >"$dest/modules.list"
}

add_module() { # NAME required|optional DEST: depth-first, so dependencies come first
  local n=${1//-/_} dep
  [[ -z ${mod_seen[$n]:-} ]] || return 0
  mod_seen[$n]=1
  if [[ -z ${mod_path[$n]:-} ]]; then
    [[ -n ${mod_builtin[$n]:-} || $2 == optional ]] && return 0
    die 125 "kernel package $kpkg has no module $1"
  fi
  decompress_module "${mod_path[$n]}" "$3/modules/$n.ko"
  for dep in $(modinfo -F depends "$3/modules/$n.ko" | tr ',' ' '); do
    add_module "$dep" required "$3"
  done
  mod_order+=("$n")
}

# Under TCG the kernel's own xz decompression takes ~3 s of every boot; qemu can instead start an
# uncompressed vmlinux directly at its PVH entry point (CONFIG_PVH). So decompress it once here;
# if that does not work out, the VM boots vmlinuz as it is, only slower.
extract_vmlinux() {
  local root=$1 out=$2 offset
  grep -qs '^CONFIG_PVH=y' "$root"/boot/config-* || return 0
  # The xz stream starts at its magic bytes FD 37 7A 58 5A 00 inside the bzImage.
  offset=$(LC_ALL=C grep -aboP '\xFD7zXZ\x00' "$out/vmlinuz" | head -n1 | cut -d: -f1 || true)
  [[ -n $offset ]] || return 0
  # xz complains about the bytes after the stream; the ELF check below is what counts.
  tail -c +"$((offset + 1))" "$out/vmlinuz" | xz -dc >"$out/vmlinux.tmp" 2>/dev/null || true
  if [[ $(head -c 4 "$out/vmlinux.tmp" | od -An -tx1 | tr -d ' ') == 7f454c46 ]]; then
    mv "$out/vmlinux.tmp" "$out/vmlinux"
  else
    rm -f "$out/vmlinux.tmp"
  fi
}

# Downloads and unpacks the kernel package into $cache/kernels/<key> (caller holds the lock).
download_kernel() {
  local work log tool
  kdir=$1
  for tool in apt-get dpkg-deb modinfo; do
    command -v "$tool" >/dev/null 2>&1 ||
      die 125 "$tool not found: needed to prepare the VM kernel (apt-get install kmod dpkg apt)"
  done
  work=$(mktemp -d "$cache/.work.XXXXXX")
  log=$work/apt.log
  # apt-get download as root warns that _apt cannot write here: harmless, kept in the log.
  if ! (cd "$work" && apt-get download "$kpkg=$kver") >"$log" 2>&1; then
    # Stale package lists (the version is gone from the mirror): refresh once and retry.
    if ! { apt-get update -qq && resolve_kernel_package &&
      (cd "$work" && apt-get download "$kpkg=$kver"); } >>"$log" 2>&1; then
      sed 's/^/vcan_run: apt: /' "$log" | tail -n 5 >&2
      rm -rf "$work"
      die 125 "cannot download $kpkg (apt-get download; as root run apt-get update)"
    fi
    kdir=$cache/kernels/${kpkg}_${kver//:/_}
  fi
  dpkg-deb -x "$work"/*.deb "$work/root"
  mkdir -p "$work/out"
  cp "$work"/root/boot/vmlinuz-* "$work/out/vmlinuz"
  extract_vmlinux "$work/root" "$work/out"
  collect_modules "$work/root" "$work/out"
  printf '%s %s\n' "$kpkg" "$kver" >"$work/out/package"
  touch "$work/out/ready"
  rm -rf "$kdir"
  mkdir -p "$(dirname "$kdir")"
  mv "$work/out" "$kdir"
  rm -rf "$work"
  ln -sfn "kernels/${kdir##*/}" "$cache/current.new.$$"
  mv -T "$cache/current.new.$$" "$cache/current"
  prepared_now=1
  # Superseded kernels (~80 MB each) and what an interrupted preparation left behind.
  find "$cache/kernels" -mindepth 1 -maxdepth 1 ! -name "${kdir##*/}" -exec rm -rf {} +
  find "$cache" -mindepth 1 -maxdepth 1 \( -name '.work.*' -o -name '.stage.*' \) -mmin +60 \
    -exec rm -rf {} +
}

# Makes sure a kernel is cached and sets kdir to it. update=1 (--prepare): also follow apt's
# newest kernel; update=0 (a run): take whatever is cached, download only when nothing is.
ensure_kernel() {
  local update=$1
  kdir=
  if [[ $update == 0 && -f $cache/current/ready ]]; then
    kdir=$(readlink -f "$cache/current")
    return
  fi
  lock_cache
  if [[ $update == 0 && -f $cache/current/ready ]]; then
    unlock_cache
    kdir=$(readlink -f "$cache/current")
    return
  fi
  if ! resolve_kernel_package; then
    # No package lists yet (fresh machine): refresh them once, as root can.
    apt-get update -qq >/dev/null 2>&1 || true
    if ! resolve_kernel_package; then
      if [[ -f $cache/current/ready ]]; then # offline but cached: good enough
        unlock_cache
        kdir=$(readlink -f "$cache/current")
        return
      fi
      die 125 "apt-cache knows no $meta_pkg: run apt-get update (as root), then tests/system/vcan_run.sh --prepare"
    fi
  fi
  kdir=$cache/kernels/${kpkg}_${kver//:/_}
  if [[ ! -f $kdir/ready ]]; then
    ((update)) || echo "vcan_run: preparing the VM kernel (one-time download of $kpkg)" >&2
    download_kernel "$kdir"
    kdir=$(readlink -f "$cache/current")
  elif [[ $(readlink -f "$cache/current" 2>/dev/null) != "$kdir" ]]; then
    ln -sfn "kernels/${kdir##*/}" "$cache/current.new.$$"
    mv -T "$cache/current.new.$$" "$cache/current"
  fi
  unlock_cache
}

# Makes sure the initramfs for $kdir and the current init script exists; sets initrd to it.
ensure_initrd() {
  local busybox hash stage
  [[ -f $init_script ]] || die 125 "$init_script is missing (the VM's /init; keep it next to vcan_run.sh)"
  busybox=$(command -v busybox 2>/dev/null) ||
    die 125 "busybox not found: apt-get install busybox-static"
  # A dynamic busybox would not run in the initramfs, which has no libc.
  if ldd "$busybox" >/dev/null 2>&1; then
    die 125 "$busybox is dynamically linked: apt-get install busybox-static"
  fi
  hash=$(cat "$init_script" "$busybox" "$kdir/modules.list" | sha256sum | cut -c1-16)
  initrd=$kdir/initrd-$hash.cpio
  if [[ ! -f $initrd ]]; then
    lock_cache
    if [[ ! -f $initrd ]]; then
      stage=$(mktemp -d "$cache/.stage.XXXXXX")
      mkdir -p "$stage/bin" "$stage/lib/vcan"
      cp "$busybox" "$stage/bin/busybox"
      ln -s busybox "$stage/bin/sh" # the #! of /init; it installs the other applet links itself
      cp "$init_script" "$stage/init"
      chmod 755 "$stage/init" "$stage/bin/busybox"
      cp -r "$kdir/modules" "$kdir/modules.list" "$stage/lib/vcan/"
      # Uncompressed cpio: the kernel unpacks it faster than it would inflate a gzip one.
      (cd "$stage" && find . -mindepth 1 | busybox cpio -o -H newc -R 0:0 2>/dev/null) \
        >"$initrd.tmp.$$"
      mv "$initrd.tmp.$$" "$initrd"
      rm -rf "$stage"
      # Older initramfs builds (earlier init scripts): drop those no run can still be opening.
      find "$kdir" -maxdepth 1 -name 'initrd-*.cpio' ! -name "${initrd##*/}" -mmin +60 -delete
    fi
    unlock_cache
  fi
}

# ---------------------------------------------------------------------------- arguments
timeout_s=900
writable=()
prepare=0
while (($#)); do
  case $1 in
    --timeout)
      (($# >= 2)) || usage 2 >&2
      timeout_s=$2
      shift 2 ;;
    --timeout=*)
      timeout_s=${1#*=}
      shift ;;
    --writable)
      (($# >= 2)) || usage 2 >&2
      writable+=("$2")
      shift 2 ;;
    --writable=*)
      writable+=("${1#*=}")
      shift ;;
    --prepare) prepare=1; shift ;;
    -h | --help) usage 0 ;;
    --) shift; break ;;
    -*) echo "vcan_run: unknown option $1" >&2; usage 2 >&2 ;;
    *) break ;;
  esac
done
[[ $timeout_s =~ ^[1-9][0-9]*$ ]] || die 2 "--timeout wants whole seconds > 0, not '$timeout_s'"
mode=${STEPCAL_VCAN:-auto}
[[ $mode == auto || $mode == host || $mode == vm ]] ||
  die 2 "STEPCAL_VCAN must be auto, host or vm, not '$mode'"

if ((prepare)); then
  if [[ $mode != vm ]] && host_has_vcan; then
    echo "vcan_run: this host has vcan0: CAN commands run here, no VM needed"
    exit 0
  fi
  prepared_now=0
  ensure_kernel 1
  ensure_initrd
  read -r p v <"$kdir/package"
  how=cached
  ((prepared_now)) && how=downloaded
  echo "vcan_run: VM kernel $p $v ready ($how) in $cache"
  exit 0
fi

(($#)) || usage 2 >&2
# A results dir may not exist yet on a fresh build tree: make it (here, where it is writable).
for d in "${writable[@]}"; do
  mkdir -p -- "$d" 2>/dev/null || true
  [[ -d $d ]] || die 2 "--writable $d: not a directory and cannot be created"
done

# ---------------------------------------------------------------------------- host path
if [[ $mode == host ]] || { [[ $mode == auto ]] && host_has_vcan; }; then
  if [[ $mode == host ]] && ! host_has_vcan; then
    die 125 "STEPCAL_VCAN=host but this host has no vcan0 (ip link add dev vcan0 type vcan failed)"
  fi
  rc=0
  timeout --kill-after=10 "$timeout_s" "$@" </dev/null || rc=$?
  ((rc != 124)) || echo "vcan_run: timeout: '$1' did not finish within ${timeout_s}s" >&2
  exit "$rc"
fi

# ---------------------------------------------------------------------------- VM path
qemu="qemu-system-x86_64"
command -v "$qemu" >/dev/null 2>&1 ||
  die 125 "$qemu not found and this host has no vcan: apt-get install qemu-system-x86 (tools/setup.sh does)"
prepared_now=0
ensure_kernel 0
ensure_initrd

run=$(mktemp -d "${TMPDIR:-/tmp}/vcan_run.XXXXXX")
run=$(cd "$run" && pwd -P)
pids=()
# shellcheck disable=SC2317 # called from the EXIT trap
cleanup() {
  local p
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  if [[ ${STEPCAL_VM_KEEP:-0} == 1 ]]; then
    echo "vcan_run: run dir kept: $run" >&2
  else
    rm -rf "$run"
  fi
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# The paths the guest mounts at: the physical ones (symlinks in the host's / resolve to them).
wpaths=()
for d in "${writable[@]}"; do
  p=$(cd "$d" && pwd -P)
  [[ $p != / ]] || die 2 "--writable /: share a directory, not the whole host"
  wpaths+=("$p")
done
for p in "$run" "$PWD" "${wpaths[@]}"; do
  [[ $p != *$'\n'* ]] || die 2 "paths with a newline cannot be shared into the VM: $p"
done

# run.sh is run by the host's bash inside the chroot, so printf %q quoting round-trips exactly
# (spaces, quotes, newlines, globs) without going near the kernel command line.
{
  printf 'cd -- %q || exit 125\n' "$PWD"
  while IFS= read -r name; do
    keep=0
    for n in "${env_names[@]}"; do [[ $name == "$n" ]] && keep=1; done
    for n in "${env_prefixes[@]}"; do [[ $name == "$n"* ]] && keep=1; done
    ((keep)) && printf 'export %s=%q\n' "$name" "${!name}"
  done < <(compgen -e)
  # So a command (tests/system/vcan_smoke.sh) can tell it runs in the VM.
  printf 'export STEPCAL_IN_VCAN_VM=1\n'
  printf 'exec'
  printf ' %q' "$@"
  printf '\n'
} >"$run/run.sh"
printf '%s\n' "$run" >"$run/hostpath"
: >"$run/writable"
kernel=$kdir/vmlinuz
[[ -f $kdir/vmlinux ]] && kernel=$kdir/vmlinux
qemu_args=(
  # -cpu max: TCG then emulates AVX2/FMA/BMI2, which x86-64-v3 binaries need. thread=single:
  # one host thread runs both vCPUs. Multi-threaded TCG made every exec/munmap (cross-CPU TLB
  # flushes stop all vCPUs) several times slower: `true` 6-8 s instead of 4 s, the smoke 18-28 s
  # instead of 9 s, and it took both host cores from ctest -j2.
  -accel "tcg,thread=${STEPCAL_VM_TCG_THREAD:-single}" -cpu max
  -smp "${STEPCAL_VM_CPUS:-2}" -m "${STEPCAL_VM_MEM_MB:-2048}"
  -nodefaults -no-user-config -display none -no-reboot
  -kernel "$kernel" -initrd "$initrd"
  # quiet: the console is only a log file, but printing a full boot log over the emulated UART
  # costs boot time. panic=-1: a dying init reboots, which -no-reboot turns into qemu exiting.
  # acpi=noirq: routing the PCI interrupts through ACPI's AML cost ~0.5 s in TCG per boot.
  # cryptomgr.notests: the crypto self-tests, mitigations=off: speculation workarounds, useless
  # in an emulated throwaway VM and slow under TCG. no_timer_check: on a loaded host the
  # emulated timer can miss the kernel's boot-time IO-APIC check ("IO-APIC + timer doesn't
  # work!", a panic); qemu's timer is known to work.
  -append "console=ttyS0 quiet panic=-1 acpi=noirq cryptomgr.notests mitigations=off tsc=reliable no_timer_check"
  -chardev "file,id=console,path=${run//,/,,}/console.log" -serial chardev:console
  -virtfs "local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap"
  -virtfs "local,path=${run//,/,,},mount_tag=vcanrun,security_model=none,multidevs=remap"
  -device "virtio-serial-pci,id=vser"
  -chardev "file,id=out,path=${run//,/,,}/out.fifo"
  -device "virtserialport,bus=vser.0,chardev=out,name=stdout"
  -chardev "file,id=err,path=${run//,/,,}/err.fifo"
  -device "virtserialport,bus=vser.0,chardev=err,name=stderr"
)
i=0
for p in "${wpaths[@]}"; do
  i=$((i + 1))
  printf 'w%d %s\n' "$i" "$p" >>"$run/writable"
  qemu_args+=(-virtfs "local,path=${p//,/,,},mount_tag=w$i,security_model=none,multidevs=remap")
done

# The guest's stdout/stderr ports end in FIFOs that cat copies to our stdout/stderr (works for
# pipes, files, terminals and sockets alike). We hold a write end of each ourselves, so the cats
# can neither block forever (qemu failing before it opens them) nor stop early.
mkfifo "$run/out.fifo" "$run/err.fifo"
cat <"$run/out.fifo" &
pids+=($!)
cat <"$run/err.fifo" >&2 &
pids+=($!)
exec {out_fd}>"$run/out.fifo" {err_fd}>"$run/err.fifo"

rc=0
timeout --kill-after=10 "$timeout_s" "$qemu" "${qemu_args[@]}" </dev/null >"$run/qemu.log" 2>&1 &
qemu_pid=$!
pids+=("$qemu_pid")
wait "$qemu_pid" || rc=$?
exec {out_fd}>&- {err_fd}>&-
wait "${pids[0]}" "${pids[1]}" || true
pids=()

if [[ -f $run/status ]]; then
  exit "$(cat "$run/status")"
fi
show_log() { # the end of the guest console and of qemu's own output: why it went wrong
  local f
  for f in console.log qemu.log; do
    [[ -s $run/$f ]] && tail -n 15 "$run/$f" | sed "s/^/vcan_run: ${f%.log}: /" >&2
  done
  return 0
}
if ((rc == 124 || rc == 137)); then
  die 124 "timeout: '$1' did not finish within ${timeout_s}s in the VM (qemu killed; --timeout SECONDS)"
fi
show_log
if [[ -s $run/error ]]; then
  die 125 "VM setup failed: $(head -n1 "$run/error")"
fi
if ((rc != 0)); then
  die 125 "$qemu failed (exit $rc): see its lines above"
fi
# The init's own last complaint (printed before the run dir was mounted, so no error file).
reason=$(grep '^vcan-vm: ' "$run/console.log" 2>/dev/null | grep -v ' at [0-9.]*s$' | tail -n1 || true)
if [[ -n $reason ]]; then
  die 125 "VM setup failed: ${reason#vcan-vm: }"
fi
if [[ -s $run/console.log ]]; then
  die 125 "the VM stopped before the command finished ($kernel): see the console lines above"
fi
die 125 "the VM stopped before its kernel printed anything ($kernel, ${STEPCAL_VM_MEM_MB:-2048} MiB): try STEPCAL_VM_KEEP=1 and read console.log, or rm -rf $cache and --prepare again"
