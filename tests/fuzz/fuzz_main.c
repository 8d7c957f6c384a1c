/*
 * libFuzzer harness for one target: built once per target with
 * -DSOOC_FUZZ_TARGET="\"<name>\"" and -fsanitize=fuzzer,address,undefined.
 *   nice -n 10 ./fuzz_calib -max_total_time=120 ../../tests/fuzz/corpus/calib
 */
#include <stdio.h>
#include <stdlib.h>

#include "fuzz_targets.h"
#include "sooc3d/core.h"

#ifndef SOOC_FUZZ_TARGET
#error "define SOOC_FUZZ_TARGET"
#endif

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    static const sooc_fuzz_target *t;
    if (!t) {
        t = sooc_fuzz_find(SOOC_FUZZ_TARGET);
        if (!t) {
            fprintf(stderr, "unknown fuzz target %s\n", SOOC_FUZZ_TARGET);
            abort();
        }
    }
    t->fn(data, size);
    return 0;
}
