#!/usr/bin/env bash
# Install everything the test suite needs: the package with its test extra, and (as root, or
# with sudo) the compilers, emulators and valgrind the C tests use. Safe to run again.
set -euo pipefail
cd "$(dirname "$0")/.."

apt_packages=(gcc clang valgrind gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm qemu-user
              gcc-arm-linux-gnueabihf binutils-arm-none-eabi libclang-rt-14-dev cmake cppcheck
              clang-format)
tools=(gcc clang valgrind arm-none-eabi-gcc qemu-system-arm qemu-arm arm-linux-gnueabihf-gcc cmake
       cppcheck clang-format)
missing=0
for tool in "${tools[@]}"; do command -v "$tool" >/dev/null 2>&1 || missing=1; done
# newlib ships no binary: look for the semihosting specs file it installs
[ -n "$(find /usr/lib/arm-none-eabi -name rdimon.specs 2>/dev/null | head -n 1)" ] || missing=1
# the libFuzzer runtime of clang (tests/test_fuzz.py)
[ -n "$(find /usr/lib/llvm-* -name 'libclang_rt.fuzzer-*.a' 2>/dev/null | head -n 1)" ] || missing=1
if [ "$missing" = 1 ]; then
  if [ "$(id -u)" = 0 ]; then sudo=""; elif command -v sudo >/dev/null 2>&1; then sudo="sudo"; else sudo="none"; fi
  if [ "$sudo" = none ]; then
    echo "setup-tests: not root and no sudo: install ${apt_packages[*]} yourself; C tests will skip" >&2
  else
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${apt_packages[@]}" >/dev/null
  fi
fi
python -m pip install -q -e '.[test,plot,control,cluster,bench]'
