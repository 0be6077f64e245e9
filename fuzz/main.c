/* SPDX-License-Identifier: BSD-3-Clause */
/* libFuzzer's entry points for one target, named at build time
 * (fuzz/CMakeLists.txt: SL_FUZZ_TARGET=sl_fuzz_<name>). */
#include "fuzz.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    sl_fuzz_init();
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return SL_FUZZ_TARGET(data, size);
}
