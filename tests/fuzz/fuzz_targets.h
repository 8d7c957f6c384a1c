/*
 * sooc3d fuzz entry points: one function per parser that takes untrusted
 * bytes. Shared by the libFuzzer harnesses (fuzz_main.c, clang) and by the
 * plain corpus replayer test_fuzz_corpus (replay.c, any compiler).
 *
 * Every entry point must return normally for ANY input (a parse error is a
 * normal return); crashes, sanitizer reports, leaks and hangs are bugs.
 */
#ifndef SOOC3D_FUZZ_TARGETS_H
#define SOOC3D_FUZZ_TARGETS_H

#include <stddef.h>
#include <stdint.h>

/* Returns 1 if the input was accepted (parsed/loaded), 0 if rejected. */
typedef int (*sooc_fuzz_fn)(const uint8_t *data, size_t n);

typedef struct sooc_fuzz_target {
    const char *name;   /* also the corpus folder tests/fuzz/corpus/<name>/ */
    sooc_fuzz_fn fn;
} sooc_fuzz_target;

/* NULL-terminated table. */
extern const sooc_fuzz_target sooc_fuzz_targets[];

/* Look up a target by name (NULL if unknown). */
const sooc_fuzz_target *sooc_fuzz_find(const char *name);

#endif
