# ctest helper: writes a translation unit that includes only HEADER and compiles it with the AVR
# compiler exactly as the team contract demands. Fails the test on any diagnostic error.
file(WRITE ${OUT} "#include \"${HEADER}\"\nint main() { return 0; }\n")
execute_process(
  COMMAND ${CXX} -std=gnu++14 -mmcu=atmega328p -Wall -Wextra -Werror -fsyntax-only
          -I${ROOT}/common -I${ROOT} ${OUT}
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "avr-g++ rejected ${HEADER}:\n${out}${err}")
endif()
