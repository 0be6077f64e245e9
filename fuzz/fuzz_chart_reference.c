/* SPDX-License-Identifier: BSD-3-Clause */
/* A ColorChecker reference file as `calibrate --chart-reference` reads it
 * (sl_chart_reference_read): CSV (L,a,b / X,Y,Z / R,G,B) or JSON. The
 * input is tried under both names: the reader chooses by extension. */
#include "fuzz.h"
#include "setlight/stitch.h"

int sl_fuzz_chart_reference(const uint8_t *data, size_t size)
{
    static const char *const names[] = {"chart.csv", "chart.json"};
    for (int k = 0; k < 2; k++) {
        const char *path = sl_fuzz_file(names[k], data, size);
        if (!path)
            return 0;
        double reference[24][3];
        sl_chart_space space;
        sl_error err = {0};
        sl_chart_reference_read(path, reference, &space, &err);
    }
    return 0;
}
