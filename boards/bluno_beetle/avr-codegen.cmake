# The firmware image's code-generation flags (size-optimised, LTO, no switch tables in RAM, byte
# enums, call prologues). One list for the image (CMakeLists.txt here) and for the test programs
# that must compile common/ exactly as the image does (tests/simavr/sim: numeric_probe.elf).
set(BTSM_AVR_CODEGEN_FLAGS
    -Os -fno-tree-switch-conversion -fshort-enums -ffunction-sections -fdata-sections
    -mcall-prologues -mstrict-X -finline-limit=10 -flto)
