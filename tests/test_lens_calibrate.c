/* SPDX-License-Identifier: BSD-3-Clause */
/* lens-calibrate's solve against known lenses: chessboard corners projected
 * through a lens whose focal length, centre and radial terms differ from the
 * nominal ones (boards up to 80 degrees off-axis, 0.1 px of noise) are
 * solved back within 0.5% focal and 1 px centre, for a fisheye and a
 * rectilinear lens. And the real Sigma 8mm photos (when the shared data is
 * there): the board found in each, an equisolid lens near the nominal one. */
#include "testing.h"

#include "setlight/stitch.h"

#include <stdlib.h>
#include <string.h>

#define COLS 7
#define ROWS 10
#define SQUARE 25.0

static void normalise(double v[3])
{
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; i < 3; i++)
        v[i] /= n;
}

static void cross(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

/* Gaussian noise (Box-Muller) of deviation sigma. */
static double noise(uint64_t *state, double sigma)
{
    double u = sl_test_uniform(state) + 1e-300, v = sl_test_uniform(state);
    return sigma * sqrt(-2.0 * log(u)) * cos(2.0 * M_PI * v);
}

/* Corners of `count` boards seen through `truth`: board b's centre at
 * theta_b off the axis (up to max_theta_deg), at distance 250-450 mm,
 * turned up to 35 deg away from facing the camera. Returns the number of
 * boards fully seen (written to corners). */
static int render_boards(const sl_lens *truth, int count, double max_theta_deg, double sigma,
                         double *corners, uint64_t *state)
{
    int kept = 0;
    for (int b = 0; b < count * 40 && kept < count; b++) {
        double theta = max_theta_deg * (M_PI / 180.0) * sqrt(sl_test_uniform(state));
        double phi = 2.0 * M_PI * sl_test_uniform(state), dist = 250.0 + 200.0 * sl_test_uniform(state);
        double dir[3] = {sin(theta) * cos(phi), sin(theta) * sin(phi), cos(theta)};
        /* Normal toward the camera, tilted by up to 35 deg. */
        double normal[3], tilt = 35.0 * (M_PI / 180.0) * sl_test_uniform(state);
        double side[3] = {sl_test_uniform(state) - 0.5, sl_test_uniform(state) - 0.5,
                          sl_test_uniform(state) - 0.5}, perp[3];
        cross(dir, side, perp);
        normalise(perp);
        for (int k = 0; k < 3; k++)
            normal[k] = -dir[k] * cos(tilt) + perp[k] * sin(tilt);
        double ex[3], ey[3], up[3] = {0.3, 1.0, 0.2};
        cross(up, normal, ex);
        normalise(ex);
        cross(normal, ex, ey);
        double spin = 2.0 * M_PI * sl_test_uniform(state), ax[3], ay[3];
        for (int k = 0; k < 3; k++) {
            ax[k] = cos(spin) * ex[k] + sin(spin) * ey[k];
            ay[k] = -sin(spin) * ex[k] + cos(spin) * ey[k];
        }
        double *out = corners + (size_t)kept * COLS * ROWS * 2;
        bool seen = true;
        for (int r = 0; r < ROWS && seen; r++)
            for (int c = 0; c < COLS && seen; c++) {
                double p[3];
                for (int k = 0; k < 3; k++)
                    p[k] = dist * dir[k] + (c - 0.5 * (COLS - 1)) * SQUARE * ax[k] +
                           (r - 0.5 * (ROWS - 1)) * SQUARE * ay[k];
                double x, y;
                seen = sl_lens_ray_to_pixel(truth, p, &x, &y);
                out[2 * (r * COLS + c)] = x + noise(state, sigma);
                out[2 * (r * COLS + c) + 1] = y + noise(state, sigma);
            }
        kept += seen;
    }
    return kept;
}

static void solve_known(sl_lens_projection proj, double focal_mm, double sensor_mm,
                        double true_scale, double max_theta_deg, const double k[3])
{
    sl_lens nominal, truth;
    sl_lens_nominal(&nominal, proj, 1600, 1200, focal_mm, sensor_mm);
    truth = nominal;
    truth.focal_px *= true_scale;
    truth.cx += 6.3;
    truth.cy -= 4.1;
    memcpy(truth.k, k, sizeof truth.k);
    truth.circle_radius_px = 0;
    enum { BOARDS = 12 };
    double *corners = malloc(sizeof(double) * BOARDS * COLS * ROWS * 2);
    uint64_t state = 77 + (uint64_t)proj;
    int count = render_boards(&truth, BOARDS, max_theta_deg, 0.1, corners, &state);
    CHECK(count == BOARDS);
    sl_lens_calibrate_options opt;
    sl_lens_calibrate_options_init(&opt);
    opt.board_cols = COLS;
    opt.board_rows = ROWS;
    opt.projection = proj;
    opt.radial_terms = 2;
    sl_lens solved = nominal;
    double rms_each[BOARDS], rms = -1, max = -1;
    sl_error err;
    CHECK_OK(sl_lens_calibrate_corners(corners, count, &opt, &solved, rms_each, NULL, &rms, &max,
                                       &err),
             &err);
    printf("  %s: focal %.3f px (truth %.3f, nominal %.3f), centre (%.3f, %.3f) (truth %.3f, "
           "%.3f), k (%.5f, %.5f), RMS %.3f px, max %.3f px\n",
           sl_lens_projection_name(proj), solved.focal_px, truth.focal_px, nominal.focal_px,
           solved.cx, solved.cy, truth.cx, truth.cy, solved.k[0], solved.k[1], rms, max);
    CHECK(fabs(solved.focal_px / truth.focal_px - 1.0) < 0.005);
    CHECK(hypot(solved.cx - truth.cx, solved.cy - truth.cy) < 1.0);
    /* The noise is 0.1 px per coordinate: 0.14 px per corner. */
    CHECK(rms > 0.08 && rms < 0.2);
    /* The solved radius agrees with the truth's over the boards' field. */
    for (double th = 0; th <= max_theta_deg; th += 5) {
        double rt = sl_lens_radius(&truth, th * M_PI / 180.0);
        double rs = sl_lens_radius(&solved, th * M_PI / 180.0);
        CHECK_MSG(fabs(rs - rt) < 1.0, "radius at %g deg: %g vs truth %g", th, rs, rt);
    }
    free(corners);
}

static void fisheye_known(void)
{
    /* The Sigma 8mm on a full-frame body, 3% longer than nominal, with a
     * radial correction that bends the rim by about 9 px. */
    double k[3] = {0.012, -0.004, 0};
    solve_known(SL_LENS_EQUISOLID, 8.0, 24.0, 1.03, 80.0, k);
}

static void rectilinear_known(void)
{
    double k[3] = {-0.08, 0.02, 0};
    solve_known(SL_LENS_RECTILINEAR, 24.0, 36.0, 0.98, 35.0, k);
}

static void bad_input(void)
{
    sl_lens_calibrate_options opt;
    sl_lens_calibrate_options_init(&opt);
    opt.board_cols = COLS;
    opt.board_rows = ROWS;
    sl_lens_calibrate_result res;
    sl_error err;
    const char *paths[1] = {"x.jpg"};
    CHECK_RESULT(sl_lens_calibrate(paths, 1, &opt, &res, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "--sensor-mm") != NULL);
    sl_lens_calibrate_result_free(&res);
}

static void sigma8mm(void)
{
    const char *dir = sl_test_data("fisheye/sigma8mm_canon6d");
    if (!dir)
        return;
    static const char *names[] = {"IMG_2843.JPG", "IMG_2900.JPG", "IMG_2901.JPG",
                                  "IMG_2920.JPG", "IMG_2921.JPG", "IMG_2922.JPG",
                                  "IMG_2923.JPG", "IMG_2938.JPG", "IMG_2939.JPG",
                                  "IMG_2940.JPG", "IMG_2941.JPG", "IMG_2942.JPG",
                                  "IMG_2943.JPG", "IMG_2944.JPG"};
    enum { N = sizeof names / sizeof names[0] };
    char paths[N][512];
    const char *p[N];
    for (int i = 0; i < N; i++) {
        snprintf(paths[i], sizeof paths[i], "%s/%s", dir, names[i]);
        p[i] = paths[i];
    }
    sl_lens_calibrate_options opt;
    sl_lens_calibrate_options_init(&opt);
    opt.board_cols = COLS;
    opt.board_rows = ROWS;
    opt.focal_mm = 8.0;
    /* The 1600 px square is the 24 mm height of the 6D's 36 x 24 mm frame. */
    opt.sensor_width_mm = 24.0;
    sl_lens_calibrate_result res;
    sl_error err;
    CHECK_OK(sl_lens_calibrate(p, N, &opt, &res, &err), &err);
    for (int i = 0; i < res.photo_count; i++) {
        printf("  %s: %s, RMS %.3f px, max %.3f px\n", names[i],
               res.photos[i].used ? "used" : res.photos[i].why, res.photos[i].rms_px,
               res.photos[i].max_px);
        CHECK(res.photos[i].found);
    }
    const sl_lens *l = &res.profile.lens;
    printf("  camera \"%s\", focal %.2f px = %.3f mm (nominal %.2f px), centre (%.2f, %.2f), "
           "k (%.5f, %.5f), %d terms, RMS %.3f px, max %.3f px\n",
           res.profile.camera, l->focal_px, res.focal_mm, res.nominal.focal_px, l->cx, l->cy,
           l->k[0], l->k[1], res.radial_terms, res.profile.rms_px, res.profile.max_px);
    CHECK(res.used >= 12);
    CHECK(fabs(res.focal_mm / 8.0 - 1.0) < 0.03);
    /* The photos' image circle (where the frame turns black, 25/255) has a
     * radius of 744-746 px: the solved lens must put 90 deg there. */
    double r90 = sl_lens_radius(l, 0.5 * M_PI);
    printf("  r(90 deg) %.1f px (the photos' circle: 745 px)\n", r90);
    CHECK(fabs(r90 - 745.0) < 8.0);
    CHECK(hypot(l->cx - 800.0, l->cy - 800.0) < 30.0);
    CHECK(res.profile.rms_px < 1.0);
    CHECK(strstr(res.profile.camera, "6D") != NULL);
    sl_lens_calibrate_result_free(&res);
}

int main(void)
{
    RUN(fisheye_known);
    RUN(rectilinear_known);
    RUN(bad_input);
    RUN(sigma8mm);
    return sl_test_finish();
}
