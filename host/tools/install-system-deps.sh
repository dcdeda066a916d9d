#!/usr/bin/env bash
# Install the system tools the test suite needs (Debian). Runs apt-get only as root and only for
# what is missing; prints what it could not install so the tests can say why they skip.
set -u
want=()
command -v cc >/dev/null 2>&1 || want+=(gcc)
command -v clang >/dev/null 2>&1 || want+=(clang)
command -v valgrind >/dev/null 2>&1 || want+=(valgrind)
command -v objdump >/dev/null 2>&1 || want+=(binutils)
for extra in "$@"; do
  case "$extra" in
    *:*) pkg=${extra%%:*}; cmd=${extra#*:} ;;
    *) pkg=$extra; cmd=$extra ;;
  esac
  command -v "$cmd" >/dev/null 2>&1 || want+=("$pkg")
done
[ ${#want[@]} -eq 0 ] && exit 0
if [ "$(id -u)" != 0 ]; then
  echo "install-system-deps: not root; missing (tests that need them will say so): ${want[*]}"
  exit 0
fi
echo "install-system-deps: apt-get install ${want[*]}"
export DEBIAN_FRONTEND=noninteractive
if ! apt-get install -y -qq "${want[@]}" >/dev/null 2>&1; then
  apt-get update -qq >/dev/null 2>&1
  apt-get install -y -qq "${want[@]}" >/dev/null 2>&1 || echo "install-system-deps: could not install: ${want[*]}"
fi
exit 0
