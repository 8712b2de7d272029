/* fuzz.h - what the libFuzzer targets of tests/fuzz share (docs/fuzzing.md): the input as a
 * NUL-terminated string, or as a file for the loaders that take a path. A failure of these
 * helpers is the harness's, not a finding: they abort with a message. */
#pragma once

#include <stddef.h>
#include <stdint.h>

/* libFuzzer's entry point, defined by each fuzz-NAME.c. */
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* libFuzzer's optional set-up, run once before the first input (fuzz-rigconf, fuzz-sessconf). */
int LLVMFuzzerInitialize(int *argc, char ***argv);

/* A malloc'ed copy of data with a NUL appended (free it); data's own NULs stay. */
char *fuzz_cstr(const uint8_t *data, size_t size);

/* Writes data to this process's scratch file for suffix (".yaml", ".ply": the loaders look at
 * the extension) in /dev/shm ($TMPDIR, else /tmp, without it) and returns its path, the same for
 * every call with that suffix; the file is removed at exit. */
const char *fuzz_file(const uint8_t *data, size_t size, const char *suffix);
