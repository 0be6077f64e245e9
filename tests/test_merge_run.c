/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_merge_run and sl_response_run from files to files, as a non-CLI
 * caller runs them: a synthetic 8-bit bracket with a sun clipped in every
 * frame is merged to the radiance EXR and its clipped mask (named beside it
 * by default) with their provenance, close to the truth; the response is
 * written as JSON; a frame that is not there refuses the run and leaves no
 * file. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "merge_fixture.h"
#include "setlight/stitch.h"
#include "testing.h"

static void test_run(void)
{
    sl_error err;
    mf_bracket b = {.width = 128, .height = 64, .frames = 5, .stops = 2, .curve = MF_GAMMA,
                    .bits = 8, .ext = "jpg", .sun = true, .noise_gain = 2e-5,
                    .noise_floor = 1e-6, .seed = 3};
    mf_result truth;
    CHECK_OK(mf_make_bracket(sl_test_tmpdir(), "br", &b, &truth, &err), &err);
    const char *paths[MF_MAX_FRAMES];
    for (int k = 0; k < b.frames; k++)
        paths[k] = truth.paths[k];
    char out[4096], mask[4096], crf[4096];
    snprintf(out, sizeof out, "%s", sl_test_path("hdr.exr"));
    snprintf(mask, sizeof mask, "%s", sl_test_path("hdr_clipped.exr"));
    snprintf(crf, sizeof crf, "%s", sl_test_path("crf.json"));

    sl_merge_run_options o;
    sl_merge_run_options_init(&o);
    CHECK(!o.no_mask && !o.mask_path && !o.ghost_path && !o.merge.deghost);
    o.frame_paths = paths;
    o.frame_count = b.frames;
    o.merge.response_mode = SL_RESPONSE_AUTO; /* recovered from the bracket */
    o.out_path = out;
    sl_merge_run_result res;
    CHECK_OK(sl_merge_run(&o, &res, &err), &err);
    CHECK(res.merge.frame_count == 5 && res.merge.width == 128 && res.merge.height == 64);
    CHECK(res.merge.clipped_pixels > 0 && !strcmp(res.mask_path, mask) && !res.ghost_path[0]);
    CHECK(res.json && strstr(res.json, "\"clipped_pixels\"") && strstr(res.json, "hdr_clipped.exr"));
    sl_merge_run_result_free(&res);

    sl_image hdr = {0};
    sl_meta m;
    sl_meta_init(&m);
    CHECK_OK(sl_image_read(out, &hdr, &m, &err), &err);
    const char *mp = sl_meta_get(&m, "setlight:merge:clipped_mask");
    CHECK(mp && strstr(mp, "hdr_clipped.exr"));
    CHECK(sl_meta_get(&m, "setlight:merge:frames") != NULL &&
          sl_meta_get(&m, "setlight:merge:response") != NULL);
    double median, p99, scale;
    int64_t n = mf_compare(&hdr, &truth, true, &median, &p99, &scale);
    printf("  %lld samples: median relative error %.4f, p99 %.4f\n", (long long)n, median, p99);
    CHECK(n > 1000 && median < 0.02);
    CHECK(sl_test_file_exists(mask));
    sl_image_free(&hdr);
    sl_meta_free(&m);

    /* The response alone. */
    o.out_path = crf;
    CHECK_OK(sl_response_run(&o, &res, &err), &err);
    CHECK(res.merge.response.nodes >= 2 && res.json && strstr(res.json, "linear_at_half"));
    sl_merge_run_result_free(&res);
    sl_response rsp;
    CHECK_OK(sl_response_read(crf, &rsp, &err), &err);
    /* The fixture's gamma curve: half the code is well below half the light. */
    CHECK(sl_response_eval(&rsp, 1, 0.5) < 0.35);
    sl_response_free(&rsp);

    /* A frame that is not there: refused, nothing written. */
    paths[2] = sl_test_path("gone.jpg");
    o.out_path = sl_test_path("none.exr");
    int files = sl_test_count_files(sl_test_tmpdir());
    CHECK_RESULT(sl_merge_run(&o, &res, &err), SL_ERR_NOT_FOUND, &err);
    CHECK(strstr(err.message, "gone.jpg") != NULL && res.json == NULL);
    sl_merge_run_result_free(&res);
    CHECK(sl_test_count_files(sl_test_tmpdir()) == files);
    mf_result_free(&truth);
}

int main(void)
{
    RUN(test_run);
    return sl_test_finish();
}
