# shellcheck shell=bash
# Sourced by tests/qemu/run-gpiosim and tests/qemu/run-powercut, whose guests boot a busybox
# initramfs with no C library of its own, and run glibc programs in it (the plcd, plcctl and
# test binaries cargo builds for the usual targets, the host's e2fsck).

# initramfs_libs ROOT SYSROOT FILE...: copies into the initramfs tree ROOT what the ELF files
# FILE... need to run: the program interpreter each names (PT_INTERP, e.g.
# /lib64/ld-linux-x86-64.so.2 or /lib/ld-linux-aarch64.so.1), at that path, and the shared
# libraries each needs (DT_NEEDED), recursively, into ROOT/lib: /lib is in the system search
# path of both the x86-64 and the arm64 glibc loaders, which is all they search without an
# ld.so.cache. SYSROOT is where the libraries come from: "" for the host's own (its
# /lib/<multiarch>, /usr/lib/<multiarch>, /lib64, /usr/lib64, /lib, /usr/lib), or another
# architecture's root, /usr/aarch64-linux-gnu for the arm64 glibc of Debian's
# libc6-arm64-cross (its lib/, lib64/). readelf reads the ELF of any architecture, where ldd
# would have to run the program. A static file needs nothing. Calls the caller's die when a
# library or interpreter is not found.
initramfs_libs() {
    local root=$1 sysroot=$2
    shift 2
    local queue=("$@") dirs=() interps=" " file interp src name lib dir
    if [ -z "$sysroot" ]; then
        dirs=("/lib/$(uname -m)-linux-gnu" "/usr/lib/$(uname -m)-linux-gnu" /lib64 /usr/lib64 /lib /usr/lib)
    else
        dirs=("$sysroot/lib" "$sysroot/lib64")
    fi
    mkdir -p "$root/lib"
    while [ ${#queue[@]} -gt 0 ]; do
        file=${queue[0]}
        queue=("${queue[@]:1}")
        LC_ALL=C readelf -h "$file" >/dev/null 2>&1 || die "$file is not an ELF file (readelf -h)"
        interp=$(LC_ALL=C readelf -lW "$file" |
            sed -n 's/^.*\[Requesting program interpreter: \(.*\)\]$/\1/p')
        if [ -n "$interp" ]; then
            # Libraries name the loader by its file name (libc.so.6 needs ld-linux-x86-64.so.2);
            # the loader, already in memory, answers to it.
            interps+="${interp##*/} "
            if [ ! -e "$root$interp" ]; then
                src=$sysroot$interp
                if [ ! -e "$src" ]; then
                    src=""
                    for dir in "${dirs[@]}"; do
                        [ ! -e "$dir/${interp##*/}" ] || { src=$dir/${interp##*/}; break; }
                    done
                fi
                [ -n "$src" ] || die "$file: its program interpreter $interp is not under ${sysroot:-/}"
                mkdir -p "$root${interp%/*}"
                cp -L "$src" "$root$interp"
            fi
        fi
        for name in $(LC_ALL=C readelf -dW "$file" | sed -n 's/^.*(NEEDED).*\[\(.*\)\]$/\1/p'); do
            [[ $interps != *" $name "* ]] || continue
            [ ! -e "$root/lib/$name" ] || continue
            lib=""
            for dir in "${dirs[@]}"; do
                [ ! -e "$dir/$name" ] || { lib=$dir/$name; break; }
            done
            [ -n "$lib" ] || die "$file needs $name, which is in none of ${dirs[*]}"
            cp -L "$lib" "$root/lib/$name"
            queue+=("$lib")
        done
    done
}
