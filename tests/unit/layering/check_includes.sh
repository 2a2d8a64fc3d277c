#!/usr/bin/env bash
# The include arrows of the folder READMEs, checked on the tree: they point down only.
#   common/    includes only other common/ headers and <stdint.h> <stddef.h> <string.h> <math.h>
#              (platform.hpp alone also <avr/pgmspace.h>)
#   hal/       common/, hal/ and <stdint.h> <stddef.h>
#   firmware/  common/, hal/, firmware/ and the four C headers of common/
#   boards/    anything but host/
#   host/      its areas in the order cli, demo, sim, residual, link, report, thermal, io: each
#              includes only areas after it and common/; only sim/, which runs the firmware core
#              on the boards, also includes hal/, firmware/ and boards/
# Usage: check_includes.sh <project root>. Exit 0 = every include allowed, 1 = some not (each
# printed with its file and line).
set -u
root=${1:?usage: check_includes.sh <project root>}
failed=0

# project includes ("dir/...") of the files below $1 whose first folder does not match $2
check_project() {
  local dir=$1 allowed=$2 hits
  hits=$(grep -rnE '^\s*#\s*include\s+"[a-z_]+/' "$root/$dir" --include='*.hpp' --include='*.cpp' --include='*.h' --include='*.c' |
         grep -vE "#\s*include\s+\"($allowed)/") || true
  if [ -n "$hits" ]; then
    echo "FAILED: $dir/ may include only ($allowed)/ of the project:"
    echo "$hits" | sed "s|^$root/||"
    failed=1
  fi
}

# system includes (<...>) of the files below $1 that are not in the list $2
check_system() {
  local dir=$1 allowed=$2 hits
  hits=$(grep -rnE '^\s*#\s*include\s+<' "$root/$dir" --include='*.hpp' --include='*.cpp' |
         grep -vE "#\s*include\s+<($allowed)>") || true
  if [ -n "$hits" ]; then
    echo "FAILED: $dir/ may include only <$allowed> of the system:"
    echo "$hits" | sed "s|^$root/||"
    failed=1
  fi
}

c_headers='stdint\.h|stddef\.h|string\.h|math\.h'
check_project common 'common'
check_system common "$c_headers|avr/pgmspace\.h"
pgm=$(grep -rlE '#\s*include\s+<avr/pgmspace\.h>' "$root/common" | sed "s|^$root/||" | grep -v '^common/platform\.hpp$') || true
if [ -n "$pgm" ]; then echo "FAILED: only common/platform.hpp includes <avr/pgmspace.h>, not: $pgm"; failed=1; fi
check_project hal 'common|hal'
check_system hal 'stdint\.h|stddef\.h'
check_project firmware 'common|hal|firmware'
check_system firmware "$c_headers"
check_project boards 'common|hal|firmware|boards'

areas=(cli demo sim residual link report thermal io)
for ((i = 0; i < ${#areas[@]}; i++)); do
  allowed="common|host/${areas[i]}"
  [ "${areas[i]}" = sim ] && allowed="$allowed|hal|firmware|boards"
  for ((j = i + 1; j < ${#areas[@]}; j++)); do allowed="$allowed|host/${areas[j]}"; done
  check_project "host/${areas[i]}" "$allowed"
done

[ $failed -eq 0 ] && echo "ok: common/, hal/, firmware/, boards/ and host/ include only what their READMEs allow"
exit $failed
