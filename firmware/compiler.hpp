// Compiler hints shared by the firmware headers.
#ifndef BTSM_FIRMWARE_COMPILER_HPP
#define BTSM_FIRMWARE_COMPILER_HPP

// Out-of-line hint for small functions called from many places: on AVR with LTO, inlining them
// everywhere costs flash the 32 KB part does not have.
#ifndef BTSM_NOINLINE
#define BTSM_NOINLINE __attribute__((noinline))
#endif

// Forced inline for tiny per-byte helpers that -finline-limit=10 would leave as calls.
#ifndef BTSM_ALWAYS_INLINE
#define BTSM_ALWAYS_INLINE inline __attribute__((always_inline))
#endif

#endif
