#!/usr/bin/env bash
# Build the millimpact container image with podman on a Debian 12 machine (as root), run its entry
# point on the default scene and print the peak contact force and the image size (docs/docker.md).
#
#   docker/build-image.sh
#
# 1. base: if podman has no docker.io/library/debian:bookworm-slim, one is made here: debootstrap
#    --variant=minbase bookworm, slimmed the way Debian's -slim images are (no docs, man pages,
#    locales; apt keeps no .debs, no translations), imported with the official image's PATH and CMD;
# 2. podman build of the repository's Dockerfile, with the first of these that works in this sandbox:
#    podman's defaults; runc with explicit --ulimit values (crun here cannot set the rlimits podman
#    asks for, nor run with cgroup v1 + v2 controllers mounted together); --isolation chroot;
# 3. the image as configured, ENTRYPOINT + CMD (`millimpact run --out /out/paper-rig`), with
#    `podman run --rm` (same choice of runtime) or, if no container starts, the fallback: podman
#    create + podman mount, then chroot into the mounted image with exactly the image's environment,
#    working directory, entry point and CMD, /proc, /dev, /sys and /out mounted in a private mount
#    namespace (gone when the run ends);
# 4. prints `millimpact --version`, F_max from /out/paper-rig/summary.json, the image size, and (unless
#    MILLIMPACT_NP2=0) F_max of `mpirun -n 2 millimpact run --out /out/np2`.
#
# Environment:
#   MILLIMPACT_BUILD_DIR  work folder, outside the repository (default /var/tmp/millimpact-image):
#                         rootfs/ (debootstrap), storage/ + run/ (podman's --root/--runroot, so the
#                         machine's default podman storage is left alone), out/ (mounted at /out)
#   MILLIMPACT_IMAGE      tag of the image (default localhost/millimpact:latest)
#   MILLIMPACT_RUN        auto (default) | podman | chroot: how the entry point runs
#   MILLIMPACT_NP2        1 (default) | 0: also run mpirun -n 2 in the image
#   MILLIMPACT_NO_CACHE   1: podman build --no-cache
#   MILLIMPACT_BUILD_CA   CA bundle that pip in the build trusts (default: this machine's
#                         /etc/ssl/certs/ca-certificates.crt, mounted read-only for the build only and
#                         passed as the Dockerfile's PIP_CERT build argument: behind a TLS-intercepting
#                         proxy the image's own CA list cannot reach PyPI); empty: none
# Afterwards: podman --root "$MILLIMPACT_BUILD_DIR/storage" --runroot "$MILLIMPACT_BUILD_DIR/run" image ls
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build_dir="${MILLIMPACT_BUILD_DIR:-/var/tmp/millimpact-image}"
image="${MILLIMPACT_IMAGE:-localhost/millimpact:latest}"
run_mode="${MILLIMPACT_RUN:-auto}"
base=docker.io/library/debian:bookworm-slim
base_path=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin   # the official image's PATH

say() { echo "[build-image] $*"; }
die() { echo "[build-image] error: $*" >&2; exit 1; }

[ "$(id -u)" -eq 0 ] || die "run as root (debootstrap, podman storage, chroot)"
case "$run_mode" in auto|podman|chroot) ;; *) die "MILLIMPACT_RUN must be auto, podman or chroot" ;; esac
case "$build_dir/" in "$repo"/*) die "MILLIMPACT_BUILD_DIR must be outside the repository ($repo)" ;; esac
mkdir -p "$build_dir/out"
podman=(podman --root "$build_dir/storage" --runroot "$build_dir/run")

need=()
command -v podman >/dev/null || need+=(podman)
command -v debootstrap >/dev/null || need+=(debootstrap)
if [ ${#need[@]} -gt 0 ]; then
    say "installing ${need[*]}"
    apt-get update -q
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${need[@]}"
fi

# ---------------------------------------------------------------- 1. the base image
slim_rootfs() {
    # what Debian's -slim variant does: dpkg leaves out docs (but copyrights), man pages, info and
    # locales, for the base and for every package installed on top of it; apt keeps no .deb files,
    # no package caches, no translations; services do not start inside image builds
    local root="$1"
    cat > "$root/etc/dpkg/dpkg.cfg.d/docker" <<'EOF'
# slim image (docker/build-image.sh): documentation, manuals and translations are not installed
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/groff/*
path-exclude /usr/share/info/*
path-exclude /usr/share/linda/*
path-exclude /usr/share/lintian/overrides/*
path-exclude /usr/share/locale/*
path-include /usr/share/locale/locale.alias
path-exclude /usr/share/man/*
EOF
    echo force-unsafe-io > "$root/etc/dpkg/dpkg.cfg.d/docker-apt-speedup"
    cat > "$root/etc/apt/apt.conf.d/docker-clean" <<'EOF'
DPkg::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
APT::Update::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
Dir::Cache::pkgcache "";
Dir::Cache::srcpkgcache "";
EOF
    echo 'Acquire::Languages "none";' > "$root/etc/apt/apt.conf.d/docker-no-languages"
    echo 'Acquire::GzipIndexes "true";' > "$root/etc/apt/apt.conf.d/docker-gzip-indexes"
    echo 'Apt::AutoRemove::SuggestsImportant "false";' > "$root/etc/apt/apt.conf.d/docker-autoremove-suggests"
    printf '#!/bin/sh\nexit 101\n' > "$root/usr/sbin/policy-rc.d"
    chmod 0755 "$root/usr/sbin/policy-rc.d"
    # the official image's sources: bookworm, bookworm-updates, bookworm-security
    rm -f "$root/etc/apt/sources.list"
    cat > "$root/etc/apt/sources.list.d/debian.sources" <<'EOF'
Types: deb
URIs: http://deb.debian.org/debian
Suites: bookworm bookworm-updates
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg

Types: deb
URIs: http://deb.debian.org/debian-security
Suites: bookworm-security
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
EOF
    find "$root/usr/share/doc" -mindepth 1 ! -type d ! -name copyright -delete
    find "$root/usr/share/doc" -mindepth 1 -type d -empty -delete
    rm -rf "$root"/usr/share/{groff,info,linda,lintian/overrides,man}/*
    find "$root/usr/share/locale" -mindepth 1 -maxdepth 1 ! -name locale.alias -exec rm -rf {} +
    rm -rf "$root"/var/lib/apt/lists/* "$root"/var/cache/apt/*.bin "$root"/var/cache/apt/archives/*.deb \
           "$root"/var/log/*.log "$root"/var/log/apt/* "$root"/tmp/*
}

if "${podman[@]}" image exists "$base"; then
    say "base: $base (already in $build_dir/storage)"
else
    rootfs="$build_dir/rootfs"
    if [ ! -f "$rootfs/.debootstrap-done" ]; then
        say "base: debootstrap --variant=minbase bookworm $rootfs"
        rm -rf "$rootfs"
        debootstrap --variant=minbase bookworm "$rootfs" http://deb.debian.org/debian > "$build_dir/debootstrap.log"
        slim_rootfs "$rootfs"
        touch "$rootfs/.debootstrap-done"
    fi
    say "base: importing $rootfs as $base ($(du -sh --exclude=.debootstrap-done "$rootfs" | cut -f1))"
    tar --numeric-owner --exclude=./.debootstrap-done -C "$rootfs" -c . |
        "${podman[@]}" import --change "ENV PATH=$base_path" --change 'CMD ["bash"]' - "$base" > /dev/null
fi

# ---------------------------------------------------------------- runtime flags that work here
# crun (podman's default) fails here: "setrlimit RLIMIT_NOFILE: Operation not permitted" (podman asks
# for rlimits above this machine's hard limits) and "cgroups in hybrid mode not supported"; runc with
# --ulimit values within the hard limits starts containers (nproc above ~64k is refused here too)
nofile="$(ulimit -Hn)"; [ "$nofile" = unlimited ] && nofile=1048576
nproc="$(ulimit -Hu)"; { [ "$nproc" = unlimited ] || [ "$nproc" -gt 32768 ]; } && nproc=32768
ulimits=(--ulimit "nofile=$nofile:$nofile" --ulimit "nproc=$nproc:$nproc")

probe_dir="$(mktemp -d "$build_dir/probe.XXXXXX")"
trap 'rm -rf "$probe_dir"' EXIT
printf 'FROM %s\nRUN true\n' "$base" > "$probe_dir/Dockerfile"
build_flags=(); build_ok=0
for flags in "" "--runtime runc ${ulimits[*]}" "--isolation chroot"; do
    if [[ "$flags" == *runc* ]] && ! command -v runc >/dev/null; then
        say "installing runc"
        DEBIAN_FRONTEND=noninteractive apt-get install -y -q runc > /dev/null
    fi
    # shellcheck disable=SC2086
    if "${podman[@]}" build --no-cache -q $flags -t localhost/millimpact-probe "$probe_dir" > /dev/null 2>&1; then
        read -r -a build_flags <<< "$flags"
        build_ok=1
        say "build: podman build ${flags:-(default runtime)} works here"
        break
    fi
done
[ "$build_ok" = 1 ] || die "no way to run podman build here (tried default, runc + --ulimit, --isolation chroot)"
"${podman[@]}" rmi -f localhost/millimpact-probe > /dev/null 2>&1 || true

# runtime for podman run: the build's, when it is an OCI runtime
run_flags=(); run_ok=0
if [ "$run_mode" != chroot ]; then
    for flags in "" "--runtime runc ${ulimits[*]}"; do
        [[ "$flags" == *runc* ]] && ! command -v runc >/dev/null && continue
        # shellcheck disable=SC2086
        if "${podman[@]}" run --rm $flags "$base" true > /dev/null 2>&1; then
            read -r -a run_flags <<< "${flags:-}"
            run_ok=1
            break
        fi
    done
fi
if [ "$run_ok" = 1 ]; then
    how=podman
    say "run: podman run ${run_flags[*]:-(default runtime)} starts containers here"
elif [ "$run_mode" = podman ]; then
    die "podman run cannot start a container here (MILLIMPACT_RUN=podman)"
else
    how=chroot
    [ "$run_mode" = chroot ] && say "run: chroot fallback (MILLIMPACT_RUN=chroot)" \
                             || say "run: podman run cannot start a container here: chroot fallback"
fi

# ---------------------------------------------------------------- 2. the image
ca="${MILLIMPACT_BUILD_CA-/etc/ssl/certs/ca-certificates.crt}"
extra=()
[ "${MILLIMPACT_NO_CACHE:-0}" = 1 ] && extra+=(--no-cache)
if [ -n "$ca" ]; then
    [ -f "$ca" ] || die "MILLIMPACT_BUILD_CA: no file $ca"
    extra+=(-v "$(readlink -f "$ca"):/run/build-ca.crt:ro" --build-arg PIP_CERT=/run/build-ca.crt)
fi
say "build: podman build ${build_flags[*]} ${extra[*]} -t $image $repo"
t0=$SECONDS
"${podman[@]}" build "${build_flags[@]}" "${extra[@]}" -t "$image" -f "$repo/Dockerfile" "$repo"
say "build: done in $((SECONDS - t0)) s"
"${podman[@]}" image prune -f > /dev/null   # earlier builds of the tag (the layer cache stays)

# ---------------------------------------------------------------- 3. the entry point
config() {  # one line per element of the image's .Config.FIELD (Entrypoint, Cmd, Env)
    "${podman[@]}" image inspect --format "{{range .Config.$1}}{{println .}}{{end}}" "$image" | sed '/^$/d'
}

# in_image ENTRY [ARG...]: run the image with $build_dir/out mounted at /out; ENTRY "" keeps the
# image's entry point, no ARG keeps its CMD (as docker/podman run do)
in_image() {
    local entry="$1"; shift
    if [ "$how" = podman ]; then
        local ep=(); [ -n "$entry" ] && ep=(--entrypoint "$entry")
        "${podman[@]}" run --rm "${run_flags[@]}" --shm-size 1g -v "$build_dir/out:/out" "${ep[@]}" "$image" "$@"
    else
        chroot_run "$entry" "$@"
    fi
}

chroot_run() {
    # podman create + podman mount, then chroot into the image's file system with exactly its Env,
    # WorkingDir, Entrypoint and Cmd, in a private mount namespace (unshare): /proc, /dev, /sys (hwloc
    # reads the CPU topology there) and /out are mounted for this process tree only and vanish with it
    local entry="$1"; shift
    local ctr mnt workdir env=() argv=() rc=0
    mapfile -t env < <(config Env)
    if [ -n "$entry" ]; then argv=("$entry"); else mapfile -t argv < <(config Entrypoint); fi
    if [ $# -gt 0 ]; then argv+=("$@"); else mapfile -t -O "${#argv[@]}" argv < <(config Cmd); fi
    workdir="$("${podman[@]}" image inspect --format '{{.Config.WorkingDir}}' "$image")"
    ctr="$("${podman[@]}" create "$image")"
    mnt="$("${podman[@]}" mount "$ctr")"
    unshare --mount --propagation private /bin/bash -euc '
        mnt="$1" out="$2"; shift 2
        mount -t proc proc "$mnt/proc"
        mount --rbind /dev "$mnt/dev"
        mount --rbind /sys "$mnt/sys"
        mkdir -p "$mnt/out"
        mount --bind "$out" "$mnt/out"
        exec chroot "$mnt" "$@"
    ' _ "$mnt" "$build_dir/out" /usr/bin/env -i "${env[@]}" HOME=/root \
        /bin/sh -c 'mkdir -p "$0" && cd "$0" && exec "$@"' "${workdir:-/}" "${argv[@]}" || rc=$?
    "${podman[@]}" umount "$ctr" > /dev/null
    "${podman[@]}" rm "$ctr" > /dev/null
    if grep -q " $mnt" /proc/mounts; then say "warning: mounts left under $mnt"; fi
    return $rc
}

entrypoint="$(config Entrypoint | paste -sd' ')"
cmd="$(config Cmd | paste -sd' ')"
[ "$entrypoint" = millimpact ] || die "the image's entry point is '$entrypoint', not millimpact"
out1="$(sed -n 's|.*--out /out/\([^ ]*\).*|\1|p' <<< "$cmd")"
[ -n "$out1" ] || die "the image's CMD '$cmd' writes nothing under /out"

fmax() {  # the top-level peak_contact_force_N of a summary.json (indent 2; no jq or Python on the host)
    sed -n 's/^  "peak_contact_force_N": *\([-0-9.eE+]*\),*$/\1/p' "$1"
}

version="$(in_image "" --version)"
say "millimpact --version in the image: $version"

rm -rf "${build_dir:?}/out/$out1"
say "entry point ($how): $entrypoint $cmd (the image's ENTRYPOINT and CMD)"
t0=$SECONDS
in_image ""
serial_s=$((SECONDS - t0))
f1="$(fmax "$build_dir/out/$out1/summary.json")"
[ -n "$f1" ] || die "no peak_contact_force_N in $build_dir/out/$out1/summary.json"

if [ "${MILLIMPACT_NP2:-1}" = 1 ]; then
    rm -rf "${build_dir:?}/out/np2"
    say "mpirun -n 2 millimpact run --out /out/np2 ($how)"
    t0=$SECONDS
    in_image mpirun -n 2 millimpact run --out /out/np2
    np2_s=$((SECONDS - t0))
    f2="$(fmax "$build_dir/out/np2/summary.json")"
fi

# ---------------------------------------------------------------- 4. the numbers
size="$("${podman[@]}" image ls --format '{{.Size}}' "$image" | head -1)"
bytes="$("${podman[@]}" image inspect --format '{{.Size}}' "$image")"
echo
say "image $image: $size ($bytes bytes, podman image ls)"
say "entry point ran with: $how$([ "$how" = podman ] && echo " run ${run_flags[*]}")"
say "version: $version"
say "F_max (default scene, serial): $f1 N = $(awk -v a="$f1" 'BEGIN { printf "%.2f", a / 1e3 }') kN ($serial_s s, /out/$out1/summary.json = $build_dir/out/$out1/summary.json)"
if [ -n "${f2:-}" ]; then
    say "F_max (default scene, mpirun -n 2): $f2 N ($np2_s s); serial - np2 = $(awk -v a="$f1" -v b="$f2" 'BEGIN { printf "%.3g", a - b }') N"
fi
