#!/usr/bin/env bash
# Builds avr_numeric_instantiation.cpp into a real ATmega328P ELF (-Os, like the firmware) and
# prints its size. Usage: avr_instantiation.sh <project root> [avr-g++]. 77 = avr-g++ missing.
set -u
root=$1
avr=${2:-}
if [ -z "$avr" ] || [ ! -x "$avr" ]; then avr=$(command -v avr-g++ || true); fi
if [ -z "$avr" ]; then
  echo "SKIPPED: avr-g++ not found (install gcc-avr avr-libc: ./run.sh deps)"
  exit 77
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
src="$root/tests/unit/common_avr_headers/avr_numeric_instantiation.cpp"
if ! "$avr" -std=gnu++14 -mmcu=atmega328p -Os -Wall -Wextra -Werror -fno-exceptions -fno-rtti \
     -I"$root/common" -I"$root" "$src" -o "$work/numeric.elf"; then
  echo "FAILED: the numeric core does not build for the ATmega328P"
  exit 1
fi
size=$(command -v avr-size || true)
if [ -n "$size" ]; then
  echo "numeric core (decode+validate+step of the reduced model, 5x ratio->CVD->Kalman->diagnosis):"
  "$size" "$work/numeric.elf"
fi
exit 0
