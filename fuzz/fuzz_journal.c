/* SPDX-License-Identifier: BSD-3-Clause */
/* A capture journal (DIR/journal.jsonl, docs/capture.md) as `capture
 * --resume` and the session rebuild read it: sl_session_write parses every
 * event (sl_journal_read) and writes DIR/session.json from them. */
#include "fuzz.h"
#include "setlight/capture.h"

int sl_fuzz_journal(const uint8_t *data, size_t size)
{
    if (!sl_fuzz_file("journal.jsonl", data, size))
        return 0;
    sl_error err = {0};
    sl_session_write(sl_fuzz_dir(), &err);
    return 0;
}
