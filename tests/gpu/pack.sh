#!/bin/bash
# Prepares here what tests/gpu/run.sh needs on a lent GPU machine, which has the CUDA driver and
# toolkit but none of pdsim's libraries and cannot install any: gpu_pack/ (ignored, carried)
# with a portable build of pdsim and of the kernel tests (any x86-64: -DPDSIM_NATIVE=OFF; sm_90
# code plus compute_90 PTX) and, beside them, every shared library they load except glibc's
# and the CUDA driver, which the machine has. Checks that it resolves from itself alone and that
# it and the working tree fit the device tool's 64 MiB. Then runs run.sh here: without a GPU it
# checks the pack and exits 2 (a dry run).
#
#   bash tests/gpu/pack.sh        # build in build-gpu/ (PDSIM_GPU_BUILD), about 30 min on 2 cores
set -euo pipefail

root=$(cd "$(dirname "$0")/../.." && pwd)
build=${PDSIM_GPU_BUILD:-$root/build-gpu}
pack=$root/gpu_pack
cd "$root"

nice -n 19 cmake -S . -B "$build" -DPDSIM_WERROR=ON -DPDSIM_NATIVE=OFF -DPDSIM_CUDA=ON \
  -DCMAKE_CUDA_ARCHITECTURES="90-real;90-virtual" >/dev/null
[ -d "$build/CMakeFiles/pdsim_cuda.dir" ] ||
  { echo "pack.sh: no nvcc found (/usr/local/cuda): the pack would hold no CUDA engine" >&2; exit 1; }
nice -n 19 cmake --build "$build" -j2 --target pdsim pdsim_kernels_tests

rm -rf "$pack"
mkdir -p "$pack/bin" "$pack/lib"
for program in pdsim pdsim_kernels_tests; do
  strip -o "$pack/bin/$program" "$build/$program"
done
# Every library the loader resolves, but glibc's (the machine's own, newer: Debian 12 builds
# need glibc 2.36) and the CUDA driver (the machine's, matching its kernel module). The C++
# runtime apart, in lib/cxx: run.sh takes it only where the machine's is older than the build's.
mkdir -p "$pack/lib/cxx"
ldd "$pack"/bin/* | awk '/=> \// {print $3}' | sort -u | while read -r library; do
  case $(basename "$library") in
    libc.so* | libm.so* | libdl.so* | libpthread.so* | librt.so* | libresolv.so* | ld-linux* | \
      libcuda.so*) ;;
    libstdc++.so* | libgcc_s.so*) cp -L "$library" "$pack/lib/cxx/" ;;
    *) cp -L "$library" "$pack/lib/" ;;
  esac
done
# The pack alone: with only its libraries and glibc on the path, nothing is missing.
if LD_LIBRARY_PATH=$pack/lib:$pack/lib/cxx ldd "$pack"/bin/* | grep "not found"; then
  echo "pack.sh: the pack lacks the libraries above" >&2
  exit 1
fi
{
  echo "commit $(git rev-parse HEAD)$(git diff --quiet HEAD || echo ' (with local changes)')"
  echo "built $(date -u +%FT%TZ) on $(uname -m), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2)"
  echo "flags -DPDSIM_NATIVE=OFF, CUDA architectures 90-real;90-virtual, $(nvcc --version | tail -1)"
  echo "glibc needed $(objdump -T "$pack"/bin/* "$pack"/lib/* 2>/dev/null |
    grep -o 'GLIBC_[0-9.]*' | sort -V | tail -1)"
  (cd "$pack" && du -b bin/* lib/*.so* lib/cxx/*)
} >"$pack/manifest.txt"

# What travels: the tracked and untracked files that git does not ignore, and the pack.
tree=$(git ls-files -z -co --exclude-standard | xargs -0 du -cb 2>/dev/null | tail -1 | cut -f1)
packed=$(du -sb "$pack" | cut -f1)
mib() { awk -v b="$1" 'BEGIN {printf "%.1f", b / 1048576}'; }
echo "gpu_pack: $(mib "$packed") MiB, working tree $(mib "$tree") MiB, together $(mib $((packed + tree))) MiB of 64"
if ((packed + tree > 64 * 1048576)); then
  echo "pack.sh: over the device tool's 64 MiB" >&2
  exit 1
fi

status=0
bash "$root/tests/gpu/run.sh" "$root/gpu_out" || status=$?
if ((status == 2)); then
  echo "pack.sh: packed; no GPU here, so run.sh made a dry run (exit 2): carry gpu_pack to a GPU"
fi
exit $status
