// CUFUND_TARGET_CLONES: put before a hot loop's function to compile it for several x86-64 instruction sets and
// pick one at load time (GCC's target_clones; the arch=x86-64-vN names need GCC 11). Empty elsewhere, with
// clang, and under CUFUND_NO_TARGET_CLONES (the sanitizer build: ifunc dispatch runs before its runtime is up).
// Results do not depend on the clone picked: the build has no FMA contraction (-ffp-contract=off).
#pragma once

#if defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 11 && defined(__x86_64__) && \
    !defined(CUFUND_NO_TARGET_CLONES)
#define CUFUND_TARGET_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define CUFUND_TARGET_CLONES
#endif
