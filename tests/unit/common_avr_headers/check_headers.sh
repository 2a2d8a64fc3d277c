#!/usr/bin/env bash
# Compiles EACH common/*.hpp alone (a one-line .cpp that includes it), globbed now so new headers
# are covered automatically:
#   avr-g++ -std=gnu++14 -mmcu=atmega328p -Wall -Wextra -Werror -fsyntax-only -I<root>/common -I<root>
#   g++ -std=c++14 -Wall -Wextra -Werror -fsyntax-only  (and again with -std=c++20)
# Usage: check_headers.sh <project root> <host g++> [avr-g++]
# Exit 0 = all compile, 1 = some failed (each failure printed with the compiler output),
# 77 = avr-g++ not installed (ctest reports the test as skipped).
set -u
root=$1
gxx=$2
avr=${3:-}
if [ -z "$avr" ] || [ ! -x "$avr" ]; then
  avr=$(command -v avr-g++ || true)
fi
if [ -z "$avr" ]; then
  echo "SKIPPED: avr-g++ not found (install gcc-avr avr-libc: ./run.sh deps); headers not checked"
  exit 77
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
shopt -s nullglob
headers=("$root"/common/*.hpp)
if [ ${#headers[@]} -eq 0 ]; then
  echo "FAILED: no headers found in $root/common"
  exit 1
fi
failed=0
for h in "${headers[@]}"; do
  name=$(basename "$h")
  this_failed=0
  src="$work/${name%.hpp}_alone.cpp"
  printf '#include "%s"\n' "$name" > "$src"
  for cmd in \
      "$avr -std=gnu++14 -mmcu=atmega328p -Wall -Wextra -Werror -fsyntax-only -I$root/common -I$root $src" \
      "$gxx -std=c++14 -Wall -Wextra -Werror -fsyntax-only -I$root/common -I$root $src" \
      "$gxx -std=c++20 -Wall -Wextra -Werror -fsyntax-only -I$root/common -I$root $src"; do
    if ! out=$($cmd 2>&1); then
      echo "FAILED: common/$name: $cmd"
      echo "$out" | head -40
      failed=1
      this_failed=1
    fi
  done
  [ $this_failed -eq 0 ] && echo "ok: common/$name (avr-g++ gnu++14, g++ c++14, g++ c++20, warnings as errors)"
done
echo "${#headers[@]} headers checked with $("$avr" --version | head -1) and $("$gxx" --version | head -1)"
exit $failed
