/* SPDX-License-Identifier: BSD-3-Clause */
/* A lens profile as `stitch --lens-profile` and `lens-calibrate` read it
 * (sl_lens_profile_read, docs/formats.md), fitted to a view of half its
 * size, then every pixel of a coarse grid mapped to a ray and back. */
#include "fuzz.h"
#include "setlight/stitch.h"

int sl_fuzz_lens_profile(const uint8_t *data, size_t size)
{
    const char *path = sl_fuzz_file("lens.json", data, size);
    if (!path)
        return 0;
    sl_lens_profile prof;
    sl_error err = {0};
    if (sl_lens_profile_read(path, &prof, &err) != SL_OK)
        return 0;
    const sl_lens *lens = &prof.lens;
    for (int j = 0; j <= 16; j++)
        for (int i = 0; i <= 16; i++) {
            double ray[3], x, y;
            if (sl_lens_pixel_to_ray(lens, lens->width * i / 16.0, lens->height * j / 16.0, ray))
                (void)sl_lens_ray_to_pixel(lens, ray, &x, &y);
        }
    (void)sl_lens_vignette(lens, 0, 0);
    return 0;
}
