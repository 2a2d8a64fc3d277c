// Compiler hints shared by the firmware headers.
#ifndef BTSM_FIRMWARE_COMPILER_HPP
#define BTSM_FIRMWARE_COMPILER_HPP

// Out-of-line hint for small functions called from many places: on AVR with LTO, inlining them
// everywhere costs flash the 32 KB part does not have.
#ifndef BTSM_NOINLINE
#define BTSM_NOINLINE __attribute__((noinline))
#endif

#endif
