/* SPDX-License-Identifier: BSD-3-Clause */
/* The solve of a fisheye stitch: the views' poses and their shared lens
 * from the overlaps (docs/stitch.md, "Solve"). */
#include "merge_private.h"
#include "stitch_private.h"

#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define DEG (M_PI / 180.0)
/* Matches of a fallen-back pair that must agree with the solved poses for
 * the pair to count as solved. */
#define KEEP_MIN_AGREE 8
/* A pair with fewer than min_inliers inliers is still solved when its
 * rotation is known to within PAIR_SIGMA_OF_BAND of the RANSAC band
 * (ransac_deg; one standard deviation, all three axes together) from at
 * least PAIR_MIN_FRACTION of min_inliers: 20 consistent rays spread over
 * an overlap fix a rotation well; the same count bunched in one spot does
 * not, nor does a chance consensus of a handful of look-alikes. Before the
 * lens is solved the residuals are mostly the nominal lens's error, so
 * the band, not a pixel, is the scale. */
#define PAIR_SIGMA_OF_BAND 0.5
#define PAIR_MIN_FRACTION 0.6

void sl_stitch_solve_options_init(sl_stitch_solve_options *o)
{
    memset(o, 0, sizeof *o);
    o->solve_poses = true;
    o->solve_focal = true;
    o->solve_centre = true;
    o->radial_terms = 2;
    o->solve_vignette = true;
    o->detector = "sift";
    o->feature_width = 1536;
    o->max_features = 6000;
    o->circle_margin = 0.02;
    o->ratio = 0.8;
    o->ransac_deg = 2.0;
    o->ransac_iterations = 2000;
    o->inlier_px = 2.0;
    o->min_inliers = 25;
    o->min_lens_inliers = 30;
    o->min_lens_spread = 0.1;
    o->max_correction_deg = 10.0;
    o->seed = 1;
    o->centre_from_circle = true;
    o->radiance_poses = true;
    o->radiance_max_sigma_deg = 0.02;
    o->radiance_lens = true;
}

const char *sl_stitch_pair_status_name(sl_stitch_pair_status s)
{
    switch (s) {
    case SL_STITCH_PAIR_SOLVED:
        return "solved";
    case SL_STITCH_PAIR_NO_OVERLAP:
        return "no overlap";
    case SL_STITCH_PAIR_FEW_MATCHES:
        return "too few matches";
    case SL_STITCH_PAIR_INCONSISTENT:
        return "inconsistent with the nominal poses";
    case SL_STITCH_PAIR_RADIANCE:
        return "solved from radiance";
    }
    return "unknown";
}

void sl_stitch_solve_result_free(sl_stitch_solve_result *res)
{
    if (!res)
        return;
    free(res->pose_nominal);
    free(res->pose);
    free(res->gain);
    free(res->features);
    free(res->pair);
    memset(res, 0, sizeof *res);
}

/* Solid angle both views see (steradians), from a Fibonacci sphere. */
static double overlap_solid_angle(const sl_lens *lens, const double a[3][3], const double b[3][3])
{
    enum { N = 4096 };
    int both = 0;
    for (int i = 0; i < N; i++) {
        double d[3], ca[3], cb[3], px, py;
        solve_sphere_dir(i, N, d);
        solve_to_camera(a, d, ca);
        solve_to_camera(b, d, cb);
        if (sl_lens_ray_to_pixel(lens, ca, &px, &py) && sl_lens_ray_to_pixel(lens, cb, &px, &py))
            both++;
    }
    return 4.0 * M_PI * both / N;
}

/* OpenCV's SIFT allocates its pyramid afresh for each view (about 0.28 GB
 * for the 1536-wide copy, in levels of 25 MB), and glibc maps and unmaps
 * blocks that large: each view faulted in some 70 000 fresh zeroed pages.
 * While the features are found, blocks under 32 MB come from the heap and
 * what is freed stays there, so the next view reuses the pages; after,
 * the freed pages go back (three 24 MP views: 110 000 fewer page faults,
 * the solve about 0.2 CPU s less, peak RSS 0.94 GB instead of 0.92). */
static void keep_freed_blocks(bool keep)
{
#ifdef __GLIBC__
    if (keep) {
        mallopt(M_MMAP_THRESHOLD, 32 << 20); /* glibc's own largest dynamic threshold */
        mallopt(M_TRIM_THRESHOLD, 1 << 30);
    } else {
        mallopt(M_TRIM_THRESHOLD, 128 << 10); /* glibc's default */
        malloc_trim(0);
    }
#else
    (void)keep;
#endif
}

static double angle_between(const double a[3], const double b[3])
{
    double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
                 a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
}

/* The rotation R with a1 = R b1 exactly and a2 on the plane of R b2. */
static bool rotation_from_two(const double a1[3], const double a2[3], const double b1[3],
                              const double b2[3], double r[3][3])
{
    double ta[3][3], tb[3][3];
    const double *p[2][2] = {{a1, a2}, {b1, b2}};
    for (int s = 0; s < 2; s++) {
        double (*t)[3] = s ? tb : ta;
        const double *u = p[s][0], *v = p[s][1];
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (len < 0.03) /* under ~2 degrees apart: no direction to turn about */
            return false;
        for (int k = 0; k < 3; k++)
            n[k] /= len;
        double m[3] = {n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0]};
        for (int k = 0; k < 3; k++) {
            t[k][0] = u[k];
            t[k][1] = n[k];
            t[k][2] = m[k];
        }
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r[i][j] = ta[i][0] * tb[j][0] + ta[i][1] * tb[j][1] + ta[i][2] * tb[j][2];
    return true;
}

static int count_inliers(const double (*ra)[3], const double (*rb)[3], int n, const double r[3][3],
                         double threshold, bool *inlier)
{
    int count = 0;
    for (int i = 0; i < n; i++) {
        double v[3];
        sl_mat3_apply(r, rb[i], v);
        bool in = angle_between(ra[i], v) < threshold;
        if (inlier)
            inlier[i] = in;
        count += in;
    }
    return count;
}

/* Least squares rotation over the inliers: Gauss-Newton on R <- Exp(w) R. */
static void refine_rotation(const double (*ra)[3], const double (*rb)[3], int n, const bool *inlier,
                            double r[3][3])
{
    for (int it = 0; it < 8; it++) {
        double a[9] = {0}, g[3] = {0};
        for (int i = 0; i < n; i++) {
            if (!inlier[i])
                continue;
            double v[3], e[3];
            sl_mat3_apply(r, rb[i], v);
            for (int k = 0; k < 3; k++)
                e[k] = v[k] - ra[i][k];
            /* d(Exp(w) v)/dw = -[v]x */
            double j[3][3] = {{0, v[2], -v[1]}, {-v[2], 0, v[0]}, {v[1], -v[0], 0}};
            for (int p = 0; p < 3; p++) {
                for (int k = 0; k < 3; k++)
                    g[p] += j[k][p] * e[k];
                for (int q = 0; q < 3; q++)
                    for (int k = 0; k < 3; k++)
                        a[p * 3 + q] += j[k][p] * j[k][q];
            }
        }
        if (!merge_cholesky_solve(a, g, 3))
            return;
        double w[3] = {-g[0], -g[1], -g[2]};
        solve_rotate(r, w);
        if (fabs(g[0]) + fabs(g[1]) + fabs(g[2]) < 1e-12)
            break;
    }
}

/* The relative rotation a = R b of a pair's camera rays by RANSAC: two
 * matches fix a rotation; the one most matches agree with wins. */
static int ransac_rotation(const double (*ra)[3], const double (*rb)[3], int n,
                           const sl_stitch_solve_options *opt, uint64_t *rng, double r[3][3],
                           bool *inlier)
{
    int best = 0;
    double threshold = opt->ransac_deg * DEG;
    for (int it = 0; it < opt->ransac_iterations && n >= 2; it++) {
        int i = (int)(sl_splitmix64(rng) % (uint64_t)n), j = (int)(sl_splitmix64(rng) % (uint64_t)n);
        double cand[3][3];
        if (i == j || !rotation_from_two(ra[i], ra[j], rb[i], rb[j], cand))
            continue;
        int c = count_inliers(ra, rb, n, cand, threshold, NULL);
        if (c > best) {
            best = c;
            memcpy(r, cand, sizeof cand);
        }
    }
    if (best < 2)
        return 0;
    count_inliers(ra, rb, n, r, threshold, inlier);
    refine_rotation(ra, rb, n, inlier, r);
    return count_inliers(ra, rb, n, r, threshold, inlier);
}

/* One standard deviation (radians, the three axes together) of the
 * rotation fitted to the inliers: the residual angle's spread times
 * sqrt(trace((sum (I - v v^T))^-1)); HUGE_VAL when it is not determined. */
static double rotation_sigma(const double (*ra)[3], const double (*rb)[3], int n,
                             const bool *inlier, const double r[3][3])
{
    double a[3][3] = {{0}}, inv[3][3], sq = 0.0;
    int used = 0;
    for (int i = 0; i < n; i++) {
        if (!inlier[i])
            continue;
        double v[3];
        sl_mat3_apply(r, rb[i], v);
        double e = angle_between(ra[i], v);
        sq += e * e;
        used++;
        for (int p = 0; p < 3; p++)
            for (int q = 0; q < 3; q++)
                a[p][q] += (p == q) - ra[i][p] * ra[i][q];
    }
    if (used < 4 || !sl_mat3_invert((const double (*)[3])a, inv))
        return HUGE_VAL;
    double trace = inv[0][0] + inv[1][1] + inv[2][2];
    return trace > 0.0 ? sqrt(sq / (used - 3) * trace) : HUGE_VAL;
}

typedef struct solve_state {
    sl_stitch_view *views;
    int count;
    const sl_stitch_solve_options *opt;
    sl_stitch_solve_result *res;
    solve_features *feat;
    double (*rot)[3][3];       /* current cam_to_world */
    double (*rot_nominal)[3][3];
    double (*pair_rot)[3][3];  /* RANSAC's a = R b per pair */
    solve_match *matches;
    int match_count, match_cap;
} solve_state;

static sl_result add_match(solve_state *st, const solve_match *m, sl_error *err)
{
    if (st->match_count == st->match_cap) {
        int cap = st->match_cap ? 2 * st->match_cap : 4096;
        solve_match *grown = realloc(st->matches, (size_t)cap * sizeof *grown);
        if (!grown)
            return sl_error_set(err, SL_ERR_NOMEM, "stitch solve: out of memory for matches");
        st->matches = grown;
        st->match_cap = cap;
    }
    st->matches[st->match_count++] = *m;
    return SL_OK;
}

/* Which features of a view (pose `own`) lie within reach_deg of the other
 * view's axis (pose `other`); NULL when out of memory (then all take part). */
static bool *seen_by(const solve_features *f, const sl_lens *lens, const double own[3][3],
                     const double other[3][3], double reach_deg)
{
    bool *keep = malloc((size_t)(f->count + 1) * sizeof *keep);
    double cos_reach = cos(reach_deg * DEG);
    for (int i = 0; keep && i < f->count; i++) {
        double ray[3], w[3];
        keep[i] = false;
        if (!sl_lens_pixel_to_ray(lens, f->xy[2 * i], f->xy[2 * i + 1], ray))
            continue;
        sl_mat3_apply(own, ray, w);
        keep[i] = other[0][2] * w[0] + other[1][2] * w[1] + other[2][2] * w[2] >= cos_reach;
    }
    return keep;
}

/* Matches one overlapping pair, keeps RANSAC's inliers, decides the pair's
 * status. */
static sl_result solve_pair(solve_state *st, int p, uint64_t *rng, sl_error *err)
{
    sl_stitch_pair *pr = &st->res->pair[p];
    const solve_features *fa = &st->feat[pr->a], *fb = &st->feat[pr->b];
    const sl_lens *lens = &st->views[0].lens;
    int *idx = NULL, n = 0;
    double (*ma)[3] = st->rot_nominal[pr->a], (*mb)[3] = st->rot_nominal[pr->b];
    /* Only what the other view may see takes part: fewer candidates,
     * fewer look-alikes for the ratio test. */
    double reach = lens->max_theta_deg + 1.5 * st->opt->max_correction_deg;
    bool *keep_a = seen_by(fa, lens, ma, mb, reach), *keep_b = seen_by(fb, lens, mb, ma, reach);
    sl_result r = solve_match_features(fa, keep_a, fb, keep_b, st->opt, &idx, &n, err);
    free(keep_a), free(keep_b);
    double (*ra)[3] = r == SL_OK ? malloc((size_t)(n + 1) * sizeof *ra) : NULL;
    double (*rb)[3] = r == SL_OK ? malloc((size_t)(n + 1) * sizeof *rb) : NULL;
    int *kept = r == SL_OK ? malloc((size_t)(n + 1) * sizeof *kept) : NULL;
    bool *inlier = r == SL_OK ? malloc((size_t)(n + 1) * sizeof *inlier) : NULL;
    if (r == SL_OK && (!ra || !rb || !kept || !inlier))
        r = sl_error_set(err, SL_ERR_NOMEM, "stitch solve: out of memory for matches");
    int m = 0;
    for (int i = 0; r == SL_OK && i < n; i++) {
        const float *xa = fa->xy + 2 * idx[2 * i], *xb = fb->xy + 2 * idx[2 * i + 1];
        double wa[3], wb[3];
        if (!sl_lens_pixel_to_ray(lens, xa[0], xa[1], ra[m]) ||
            !sl_lens_pixel_to_ray(lens, xb[0], xb[1], rb[m]))
            continue;
        sl_mat3_apply(ma, ra[m], wa);
        sl_mat3_apply(mb, rb[m], wb);
        /* Far from where the nominal poses put it: a repeated texture. */
        if (angle_between(wa, wb) > 1.5 * st->opt->max_correction_deg * DEG)
            continue;
        kept[m++] = i;
    }
    pr->matches = m;
    double rel[3][3], nominal[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            nominal[i][j] = ma[0][i] * mb[0][j] + ma[1][i] * mb[1][j] + ma[2][i] * mb[2][j];
    int inliers = r == SL_OK ? ransac_rotation((const double (*)[3])ra, (const double (*)[3])rb,
                                               m, st->opt, rng, rel, inlier)
                             : 0;
    pr->inliers = inliers;
    double off = inliers ? solve_rotation_angle(rel, nominal) : 0.0;
    int floor = (int)ceil(PAIR_MIN_FRACTION * st->opt->min_inliers);
    double sigma = inliers >= floor ? rotation_sigma((const double (*)[3])ra,
                                                     (const double (*)[3])rb, m, inlier, rel) / DEG
                                    : HUGE_VAL;
    double max_sigma = PAIR_SIGMA_OF_BAND * st->opt->ransac_deg;
    bool enough = inliers >= st->opt->min_inliers || sigma <= max_sigma;
    if (r != SL_OK) {
        /* the error is the caller's */
    } else if (!enough) {
        pr->status = SL_STITCH_PAIR_FEW_MATCHES;
        pr->fallback = true;
        if (inliers >= floor)
            snprintf(pr->why, sizeof pr->why,
                     "%d features and %d, %d matches, %d consistent fixing the rotation to %.2f "
                     "deg (at least %d needed, or %.2f deg)",
                     fa->count, fb->count, m, inliers, sigma, st->opt->min_inliers, max_sigma);
        else
            snprintf(pr->why, sizeof pr->why,
                     "%d features and %d, %d matches, %d consistent (at least %d needed)",
                     fa->count, fb->count, m, inliers, st->opt->min_inliers);
        /* Too few to fix a rotation on their own, but once the other pairs
         * have placed both views its matches are judged against that
         * (keep_agreeing_pairs): they start as outliers. */
        for (int i = 0; i < m && r == SL_OK; i++) {
            const float *xa = fa->xy + 2 * idx[2 * kept[i]], *xb = fb->xy + 2 * idx[2 * kept[i] + 1];
            solve_match sm = {.pair = p, .a = pr->a, .b = pr->b,
                              .pa = {xa[0], xa[1]}, .pb = {xb[0], xb[1]}, .inlier = false};
            r = add_match(st, &sm, err);
        }
    } else if (off > st->opt->max_correction_deg) {
        pr->status = SL_STITCH_PAIR_INCONSISTENT;
        pr->fallback = true;
        snprintf(pr->why, sizeof pr->why,
                 "%d matches agree on a rotation %.1f deg from the nominal one (at most %.1f)",
                 inliers, off, st->opt->max_correction_deg);
    } else {
        pr->status = SL_STITCH_PAIR_SOLVED;
        memcpy(st->pair_rot[p], rel, sizeof rel);
        if (inliers < st->opt->min_inliers)
            snprintf(pr->why, sizeof pr->why,
                     "%d matches, %d consistent: fewer than %d, but they fix the rotation to "
                     "%.2f deg (at most %.2f)",
                     m, inliers, st->opt->min_inliers, sigma, max_sigma);
        for (int i = 0; i < m && r == SL_OK; i++) {
            const float *xa = fa->xy + 2 * idx[2 * kept[i]], *xb = fb->xy + 2 * idx[2 * kept[i] + 1];
            solve_match sm = {.pair = p, .a = pr->a, .b = pr->b,
                              .pa = {xa[0], xa[1]}, .pb = {xb[0], xb[1]}, .inlier = inlier[i]};
            r = add_match(st, &sm, err);
        }
    }
    free(idx), free(ra), free(rb), free(kept), free(inlier);
    return r;
}

/* Places the views the solved pairs reach from root (held at its nominal
 * pose), breadth first; group[v] = root for each. */
static void place_from(solve_state *st, int root, bool *free_view, int *group, int *queue)
{
    int head = 0, tail = 0;
    queue[tail++] = root;
    group[root] = root;
    while (head < tail) {
        int v = queue[head++];
        for (int p = 0; p < st->res->pairs; p++) {
            const sl_stitch_pair *pr = &st->res->pair[p];
            if (pr->status != SL_STITCH_PAIR_SOLVED || (pr->a != v && pr->b != v))
                continue;
            int o = pr->a == v ? pr->b : pr->a;
            if (group[o] >= 0)
                continue;
            double (*rel)[3] = st->pair_rot[p], t[3][3];
            if (pr->a == v) { /* M_b = M_a R */
                sl_mat3_mul((const double (*)[3])st->rot[v], (const double (*)[3])rel, st->rot[o]);
            } else { /* M_a = M_b R^T */
                for (int i = 0; i < 3; i++)
                    for (int j = 0; j < 3; j++)
                        t[i][j] = rel[j][i];
                sl_mat3_mul((const double (*)[3])st->rot[v], (const double (*)[3])t, st->rot[o]);
            }
            group[o] = root;
            free_view[o] = st->opt->solve_poses;
            queue[tail++] = o;
        }
    }
}

/* Starting rotations: view 0's nominal one, then along the solved pairs
 * (breadth first). A group of views that solved pairs join to each other
 * but not to view 0 is placed the same way from its first view, held at
 * its nominal pose: the seams inside the group are solved, its pairs with
 * the rest fall back (else its pairs would count as solved and place
 * nothing). Views no solved pair reaches keep their nominal pose and stay
 * fixed. */
static void initial_rotations(solve_state *st, bool *free_view, int *group)
{
    int count = st->count;
    int *queue = malloc((size_t)count * sizeof *queue);
    memcpy(st->rot, st->rot_nominal, (size_t)count * sizeof *st->rot);
    for (int v = 0; v < count; v++) {
        free_view[v] = false;
        group[v] = -1;
    }
    if (!queue)
        return;
    for (int v = 0; v < count; v++)
        if (group[v] < 0)
            place_from(st, v, free_view, group, queue);
    free(queue);
}

/* The matches of a pair that fell back take part only when the solved
 * pairs join its two views (else nothing places one against the other);
 * the rest are dropped. */
static void drop_unplaced_matches(solve_state *st, const int *group)
{
    int kept = 0;
    for (int i = 0; i < st->match_count; i++) {
        const solve_match *m = &st->matches[i];
        if (st->res->pair[m->pair].status == SL_STITCH_PAIR_SOLVED ||
            group[m->a] == group[m->b])
            st->matches[kept++] = *m;
    }
    st->match_count = kept;
}

/* A pair that fell back for too few matches is solved after all when at
 * least min_agree of its matches agree with the poses the other pairs
 * solved (to the final inlier threshold); otherwise its matches leave the
 * adjustment. */
static void keep_agreeing_pairs(solve_state *st, int min_agree)
{
    sl_stitch_solve_result *res = st->res;
    for (int p = 0; p < res->pairs; p++) {
        sl_stitch_pair *pr = &res->pair[p];
        if (pr->status != SL_STITCH_PAIR_FEW_MATCHES)
            continue;
        int agree = 0;
        for (int i = 0; i < st->match_count; i++)
            agree += st->matches[i].pair == p && st->matches[i].inlier;
        if (agree >= min_agree) {
            pr->status = SL_STITCH_PAIR_SOLVED;
            pr->fallback = false;
            snprintf(pr->why, sizeof pr->why,
                     "%d matches, %d consistent: too few for a rotation of its own, but %d agree "
                     "with the poses of the other pairs",
                     pr->matches, pr->inliers, agree);
        } else {
            for (int i = 0; i < st->match_count; i++)
                if (st->matches[i].pair == p)
                    st->matches[i].inlier = false;
        }
    }
}

/* A pair solved on its own whose inliers all disagree with the poses
 * solved in the end places nothing: it is reported as fallen back, not as
 * solved with no inliers. */
static void drop_disagreeing_pairs(solve_state *st)
{
    for (int p = 0; p < st->res->pairs; p++) {
        sl_stitch_pair *pr = &st->res->pair[p];
        if (pr->status != SL_STITCH_PAIR_SOLVED || pr->inliers > 0)
            continue;
        pr->status = SL_STITCH_PAIR_INCONSISTENT;
        pr->fallback = true;
        snprintf(pr->why, sizeof pr->why,
                 "%d matches, none of them consistent with the poses solved from all pairs",
                 pr->matches);
    }
}

/* Each group of views the solved pairs do not join to view 0's (a
 * featureless zenith) turned by the radiance of its overlaps with the
 * views placed so far (solve_radiance_turn); its fallen-back pairs with
 * them say how, or why not. Needs the lens and vignetting solved: an
 * unknown falloff differs between the two sides of an overlap and would
 * pull the pose. */
static void place_by_radiance(solve_state *st, const sl_lens *lens, int *group)
{
    sl_stitch_solve_result *res = st->res;
    int count = st->count;
    bool moving[SL_STITCH_MAX_VIEWS], placed_view[SL_STITCH_MAX_VIEWS];
    if (count > SL_STITCH_MAX_VIEWS)
        return;
    for (int root = 0; root < count; root++) {
        bool any = false;
        for (int v = 0; v < count; v++) {
            moving[v] = group[v] == root && group[0] != root;
            placed_view[v] = group[v] == group[0];
            any |= moving[v];
        }
        if (!any)
            continue;
        char why[160];
        bool placed = solve_radiance_turn(count, st->feat, st->rot, moving, placed_view, lens,
                                          res->gain,
                                          st->opt->max_correction_deg,
                                          st->opt->radiance_max_sigma_deg, why, sizeof why);
        for (int p = 0; p < res->pairs; p++) {
            sl_stitch_pair *pr = &res->pair[p];
            bool across = (moving[pr->a] && placed_view[pr->b]) ||
                          (moving[pr->b] && placed_view[pr->a]);
            if (!pr->fallback || pr->status == SL_STITCH_PAIR_NO_OVERLAP || !across)
                continue;
            if (placed) {
                pr->status = SL_STITCH_PAIR_RADIANCE;
                pr->fallback = false;
                res->pairs_radiance++;
                res->pairs_fallback--;
                snprintf(pr->why, sizeof pr->why, "%s", why);
            } else {
                size_t used = strlen(pr->why);
                snprintf(pr->why + used, sizeof pr->why - used, "; %s", why);
            }
        }
        if (placed)
            for (int v = 0; v < count; v++)
                if (moving[v])
                    group[v] = group[0];
    }
}

/* The features' residuals may grow by this much (pixels of the full
 * views) under the lens the radiance refined: more, and the two disagree
 * about the geometry; the features' lens stands. */
#define RADIANCE_MAX_RMS_RISE_PX 0.1

static void measure(solve_state *st, const sl_lens *lens);

/* Step 8: the lens refined by the overlaps' smooth radiance
 * (solve_radiance_lens), the features' residuals measured again under it. */
static void refine_by_radiance(solve_state *st, const bool *free_view, sl_lens *lens)
{
    sl_stitch_solve_result *res = st->res;
    int count = st->count;
    double rot[SL_STITCH_MAX_VIEWS][3][3], gain[SL_STITCH_MAX_VIEWS];
    sl_lens before = *lens;
    double rms_before = res->rms_px;
    memcpy(rot, st->rot, (size_t)count * sizeof *st->rot);
    memcpy(gain, res->gain, (size_t)count * sizeof *gain);
    solve_radiance_lens_result rl;
    res->radiance_lens = solve_radiance_lens(count, st->feat, st->rot, free_view, res->pair,
                                             res->pairs, st->matches, st->match_count, st->opt,
                                             lens, res->gain, &rl);
    res->radiance_lens_samples = rl.samples;
    res->radiance_lens_rms[0] = rl.rms_start;
    res->radiance_lens_rms[1] = rl.rms;
    res->radiance_lens_focal_change = rl.focal_change;
    if (!res->radiance_lens)
        return;
    measure(st, lens);
    if (res->rms_px <= rms_before + RADIANCE_MAX_RMS_RISE_PX)
        return;
    res->radiance_lens = false;
    *lens = before;
    memcpy(st->rot, rot, (size_t)count * sizeof *st->rot);
    memcpy(res->gain, gain, (size_t)count * sizeof *gain);
    measure(st, lens);
}

/* Reprojection errors of the inliers, overall and per pair. */
static void measure(solve_state *st, const sl_lens *lens)
{
    sl_lens u;
    solve_lens_unbounded(lens, &u);
    sl_stitch_solve_result *res = st->res;
    double *sum = calloc((size_t)res->pairs, sizeof *sum), total = 0.0;
    int *n = calloc((size_t)res->pairs, sizeof *n);
    res->inliers = 0;
    res->rms_px = res->max_px = 0.0;
    for (int p = 0; p < res->pairs; p++)
        res->pair[p].rms_px = res->pair[p].max_px = 0.0;
    for (int i = 0; i < st->match_count; i++) {
        const solve_match *m = &st->matches[i];
        double e1, e2;
        if (!m->inlier || solve_match_error(m, st->rot, &u, &e1, &e2) < 0.0)
            continue;
        sl_stitch_pair *pr = &res->pair[m->pair];
        double e = e1 > e2 ? e1 : e2, sq = 0.5 * (e1 * e1 + e2 * e2);
        pr->max_px = e > pr->max_px ? e : pr->max_px;
        res->max_px = e > res->max_px ? e : res->max_px;
        total += sq;
        res->inliers++;
        if (sum && n) {
            sum[m->pair] += sq;
            n[m->pair]++;
        }
    }
    res->rms_px = res->inliers ? sqrt(total / res->inliers) : 0.0;
    for (int p = 0; sum && n && p < res->pairs; p++) {
        res->pair[p].rms_px = n[p] ? sqrt(sum[p] / n[p]) : 0.0;
        if (res->pair[p].status == SL_STITCH_PAIR_SOLVED)
            res->pair[p].inliers = n[p];
    }
    free(sum), free(n);
}

/* Marks as inliers the matches of solved pairs within threshold pixels. */
static void select_inliers(solve_state *st, const sl_lens *lens, double threshold)
{
    sl_lens u;
    solve_lens_unbounded(lens, &u);
    for (int i = 0; i < st->match_count; i++) {
        double e = solve_match_error(&st->matches[i], st->rot, &u, NULL, NULL);
        st->matches[i].inlier = e >= 0.0 && e < threshold;
    }
}

/* How well the inliers of the solved pairs tie the lens down: their count
 * and the RMS distance of their points (both ends) from the centroid of
 * the points in the same view, over the circle radius. */
static int lens_evidence(const solve_state *st, const sl_lens *lens, double *spread)
{
    double n[SL_STITCH_MAX_VIEWS] = {0}, sx[SL_STITCH_MAX_VIEWS] = {0},
           sy[SL_STITCH_MAX_VIEWS] = {0}, sq[SL_STITCH_MAX_VIEWS] = {0};
    int inliers = 0;
    for (int i = 0; i < st->match_count; i++) {
        const solve_match *m = &st->matches[i];
        if (!m->inlier || st->res->pair[m->pair].status != SL_STITCH_PAIR_SOLVED ||
            m->a >= SL_STITCH_MAX_VIEWS || m->b >= SL_STITCH_MAX_VIEWS)
            continue;
        inliers++;
        const int v[2] = {m->a, m->b};
        const double *p[2] = {m->pa, m->pb};
        for (int k = 0; k < 2; k++) {
            n[v[k]] += 1;
            sx[v[k]] += p[k][0];
            sy[v[k]] += p[k][1];
            sq[v[k]] += p[k][0] * p[k][0] + p[k][1] * p[k][1];
        }
    }
    double total = 0, var = 0;
    for (int v = 0; v < SL_STITCH_MAX_VIEWS; v++)
        if (n[v] > 0) {
            double mx = sx[v] / n[v], my = sy[v] / n[v];
            var += fmax(0.0, sq[v] - n[v] * (mx * mx + my * my));
            total += n[v];
        }
    double radius = lens->circle_radius_px > 0
                        ? lens->circle_radius_px
                        : 0.5 * hypot(lens->width, lens->height);
    *spread = total > 0 ? sqrt(var / total) / radius : 0.0;
    return inliers;
}

/* Drops the inliers further than threshold pixels. */
static void prune_inliers(solve_state *st, const sl_lens *lens, double threshold)
{
    sl_lens u;
    solve_lens_unbounded(lens, &u);
    for (int i = 0; i < st->match_count; i++)
        if (st->matches[i].inlier)
            st->matches[i].inlier =
                solve_match_error(&st->matches[i], st->rot, &u, NULL, NULL) < threshold;
}

/* The image circle's edge is where the lens's field ends (max_theta_deg:
 * 90 deg for a nominal fisheye, a profile's own field), so its radius
 * gives the focal length given that field. Used only when the overlaps
 * cannot solve the lens, and only when it agrees with the nominal focal
 * within CIRCLE_FOCAL_AGREE: further off, the field is not what the lens
 * model says (a 190 deg fisheye's circle is 3.3% wider than a 180 deg
 * one's) or the circle is not the lens's. The result says which. */
#define CIRCLE_FOCAL_AGREE 0.03
static void focal_from_circle(sl_lens *lens, sl_stitch_solve_result *res)
{
    if (lens->projection == SL_LENS_RECTILINEAR || !(lens->circle_radius_px > 0.0))
        return;
    double edge = sl_lens_radius(lens, lens->max_theta_deg * DEG);
    if (!(edge > 0.0))
        return;
    double focal = lens->focal_px * lens->circle_radius_px / edge;
    double change = focal / lens->focal_px - 1.0;
    size_t used = strlen(res->lens_note);
    const char *sep = used ? "; " : "";
    if (fabs(change) > CIRCLE_FOCAL_AGREE) {
        snprintf(res->lens_note + used, sizeof res->lens_note - used,
                 "%sthe circle's focal (%.4g deg field) is %+.1f%% off: not used",
                 sep, 2.0 * lens->max_theta_deg, 100.0 * change);
        return;
    }
    if (fabs(change) < 1e-9)
        return;
    snprintf(res->lens_note + used, sizeof res->lens_note - used,
             "%sfocal %.2f px from the circle (%.4g deg field, %+.2f%%)", sep,
             focal, 2.0 * lens->max_theta_deg, 100.0 * change);
    lens->focal_px = focal;
    res->lens_held = true;
}

/* The adjustment: a loose first round (the nominal lens puts the circle's
 * edge degrees off), the matches re-judged in pixels of the features'
 * copies (scale s) as the lens is solved, then the inliers refined to a
 * hundredth of a pixel at full resolution and adjusted again, dropping what
 * the refinement could not place. */
static void adjust_rounds(solve_state *st, const bool *free_view, sl_lens *lens,
                          const sl_stitch_solve_options *opt, const solve_centre_prior *pull,
                          double s)
{
    sl_stitch_solve_result *res = st->res;
    const double rounds[] = {0.0, 8.0, 4.0, 1.0};
    for (int k = 0; k < 4; k++) {
        if (k > 0)
            select_inliers(st, lens, rounds[k] * opt->inlier_px * s);
        res->iterations += solve_adjust(st->matches, st->match_count, st->rot, free_view,
                                        st->count, lens, opt, 1.5 * s, pull, NULL);
    }
    solve_refine_matches(st->views, st->matches, st->match_count, st->rot, lens,
                         s > 2.0 ? 0.5 * s : 1.0);
    for (int k = 0; k < 2; k++) {
        res->iterations += solve_adjust(st->matches, st->match_count, st->rot, free_view,
                                        st->count, lens, opt, 0.5, pull, NULL);
        measure(st, lens);
        prune_inliers(st, lens, fmax(0.5, 3.0 * res->rms_px));
    }
}

/* Whether the centre the overlaps solve alone, from the solution with the
 * circles' centre, agrees with the circles': when not, the circle is not
 * centred on the lens's axis (or not the lens's). */
static bool centre_agrees(solve_state *st, const bool *free_view, const sl_lens *lens,
                          const sl_stitch_solve_options *opt, const solve_centre_prior *prior)
{
    size_t bytes = (size_t)st->count * sizeof *st->rot;
    double (*rot)[3][3] = malloc(bytes);
    if (!rot)
        return true;
    memcpy(rot, st->rot, bytes);
    sl_lens alone = *lens;
    double cov[3];
    st->res->iterations += solve_adjust(st->matches, st->match_count, rot, free_view, st->count,
                                        &alone, opt, 0.5, NULL, cov);
    free(rot);
    st->res->centre_from_circle = solve_centre_agrees(prior, &alone, cov, st->res);
    return st->res->centre_from_circle;
}

static sl_result check_views(const sl_stitch_view *views, int count, sl_error *err)
{
    if (count < 1 || !views)
        return sl_error_set(err, SL_ERR_USAGE, "stitch solve: no views");
    const sl_stitch_view *v0 = &views[0];
    for (int i = 0; i < count; i++) {
        const sl_stitch_view *v = &views[i];
        const char *name = v->name ? v->name : "view";
        if (!v->radiance || !v->radiance->data || v->radiance->width < 16 ||
            v->radiance->height < 16)
            return sl_error_set(err, SL_ERR_INPUT, "%s: no image", name);
        if (v->weight && (v->weight->width != v->radiance->width ||
                          v->weight->height != v->radiance->height))
            return sl_error_set(err, SL_ERR_INPUT, "%s: its weight image is %dx%d, the view %dx%d",
                                name, v->weight->width, v->weight->height, v->radiance->width,
                                v->radiance->height);
        if (!(v->lens.focal_px > 0.0) || !isfinite(v->lens.focal_px))
            return sl_error_set(err, SL_ERR_INPUT, "%s: no lens (focal length unknown)", name);
        if (v->radiance->width != v0->radiance->width ||
            v->radiance->height != v0->radiance->height)
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: %dx%d, but %s is %dx%d (one stitch is one camera and lens)",
                                name, v->radiance->width, v->radiance->height,
                                v0->name ? v0->name : "view 0", v0->radiance->width,
                                v0->radiance->height);
        if (v->lens.projection != v0->lens.projection ||
            fabs(v->lens.focal_px - v0->lens.focal_px) > 1e-6 * v0->lens.focal_px)
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: its lens (%s, %.1f px) is not that of %s (%s, %.1f px); one "
                                "stitch is one camera and lens",
                                name, sl_lens_projection_name(v->lens.projection), v->lens.focal_px,
                                v0->name ? v0->name : "view 0",
                                sl_lens_projection_name(v0->lens.projection), v0->lens.focal_px);
    }
    return SL_OK;
}

sl_result sl_stitch_solve(sl_stitch_view *views, int count, const sl_stitch_solve_options *opt,
                          sl_stitch_solve_result *res, sl_error *err)
{
    memset(res, 0, sizeof *res);
    double start = sl_seconds();
    sl_stitch_solve_options defaults;
    if (!opt) {
        sl_stitch_solve_options_init(&defaults);
        opt = &defaults;
    }
    sl_result r = check_views(views, count, err);
    if (r != SL_OK)
        return r;
    int pairs = count * (count - 1) / 2;
    res->views = count;
    res->pose_nominal = calloc((size_t)count, sizeof *res->pose_nominal);
    res->pose = calloc((size_t)count, sizeof *res->pose);
    res->gain = calloc((size_t)count, sizeof *res->gain);
    res->features = calloc((size_t)count, sizeof *res->features);
    res->pair = calloc((size_t)(pairs + 1), sizeof *res->pair);
    solve_state st = {.views = views, .count = count, .opt = opt, .res = res};
    st.feat = calloc((size_t)count, sizeof *st.feat);
    st.rot = malloc((size_t)count * sizeof *st.rot);
    st.rot_nominal = malloc((size_t)count * sizeof *st.rot_nominal);
    st.pair_rot = malloc((size_t)(pairs + 1) * sizeof *st.pair_rot);
    bool *free_view = calloc((size_t)count, sizeof *free_view);
    int *group = calloc((size_t)count, sizeof *group);
    if (!group || !res->pose_nominal || !res->pose || !res->gain || !res->features || !res->pair ||
        !st.feat || !st.rot || !st.rot_nominal || !st.pair_rot || !free_view) {
        r = sl_error_set(err, SL_ERR_NOMEM, "stitch solve: out of memory");
        goto done;
    }
    sl_lens lens = views[0].lens;
    res->lens_nominal = lens;
    for (int v = 0; v < count; v++) {
        res->pose_nominal[v] = views[v].pose;
        res->gain[v] = 1.0;
        sl_view_pose_matrix(&views[v].pose, st.rot_nominal[v]);
    }
    res->pairs = pairs;
    bool *needs = calloc((size_t)count, sizeof *needs);
    for (int a = 0, p = 0; a < count; a++)
        for (int b = a + 1; b < count; b++, p++) {
            sl_stitch_pair *pr = &res->pair[p];
            pr->a = a;
            pr->b = b;
            pr->overlap_sr = overlap_solid_angle(&lens, (const double (*)[3])st.rot_nominal[a],
                                                 (const double (*)[3])st.rot_nominal[b]);
            /* under ~1% of a fisheye's hemisphere: not a usable overlap */
            if (pr->overlap_sr < 0.06) {
                pr->status = SL_STITCH_PAIR_NO_OVERLAP;
                pr->fallback = true;
                snprintf(pr->why, sizeof pr->why, "the nominal poses overlap by %.3f sr",
                         pr->overlap_sr);
            } else if (needs) {
                needs[a] = needs[b] = true;
            }
        }
    bool wanted = opt->solve_poses || opt->solve_focal || opt->solve_centre ||
                  opt->radial_terms > 0 || opt->solve_vignette;
    keep_freed_blocks(true);
    for (int v = 0; r == SL_OK && v < count && wanted; v++)
        if (needs && needs[v]) {
            r = solve_find_features(&views[v], opt, &st.feat[v], err);
            res->features[v] = st.feat[v].count;
        }
    keep_freed_blocks(false);
    free(needs);
    res->seconds_features = sl_seconds() - start;
    double t = sl_seconds();
    uint64_t rng = opt->seed;
    for (int p = 0; r == SL_OK && wanted && p < pairs; p++)
        if (res->pair[p].status != SL_STITCH_PAIR_NO_OVERLAP)
            r = solve_pair(&st, p, &rng, err);
    res->seconds_match = sl_seconds() - t;
    t = sl_seconds();
    if (r != SL_OK)
        goto done;
    for (int p = 0; p < pairs; p++) {
        res->pairs_solved += res->pair[p].status == SL_STITCH_PAIR_SOLVED;
        res->pairs_fallback += res->pair[p].fallback;
    }
    initial_rotations(&st, free_view, group);
    drop_unplaced_matches(&st, group);
    /* A few matches in one corner of the overlaps fit the lens to
     * themselves: the lens moves only on enough inliers spread over the
     * circle, else the poses alone are solved. */
    sl_stitch_solve_options adjust_opt = *opt;
    opt = &adjust_opt;
    bool focal_wanted = opt->solve_focal;
    bool lens_wanted = opt->solve_focal || opt->solve_centre || opt->radial_terms > 0;
    if (res->pairs_solved > 0 && lens_wanted) {
        res->lens_inliers = lens_evidence(&st, &lens, &res->lens_spread);
        bool few = res->lens_inliers < opt->min_lens_inliers;
        if (few || res->lens_spread < opt->min_lens_spread) {
            res->lens_held = true;
            snprintf(res->lens_note, sizeof res->lens_note,
                     "lens kept nominal: %d inliers spread over %.2f of the circle radius "
                     "(needs %d and %.2f); only the poses solved",
                     res->lens_inliers, res->lens_spread, opt->min_lens_inliers,
                     opt->min_lens_spread);
            adjust_opt.solve_focal = adjust_opt.solve_centre = false;
            adjust_opt.radial_terms = 0;
        }
    }
    if ((res->pairs_solved == 0 || res->lens_held) && focal_wanted)
        focal_from_circle(&lens, res);
    /* The circles' centre: a measurement of the optical centre beside the
     * overlaps' (and the centre itself when they cannot solve it). */
    solve_centre_prior prior;
    bool have_prior = opt->centre_from_circle && opt->solve_centre &&
                      solve_centre_from_circles(views, count, opt, &prior, res);
    if (have_prior) {
        lens.cx = prior.cx;
        lens.cy = prior.cy;
    }
    if (have_prior && (res->pairs_solved == 0 || !adjust_opt.solve_centre)) {
        res->centre_from_circle = true;
        solve_centre_note(res, "centre from the image circles alone (%d views): the overlaps "
                               "do not solve it",
                          res->circle_views);
    }
    const solve_centre_prior *pull = have_prior && adjust_opt.solve_centre ? &prior : NULL;
    if (res->pairs_solved > 0) {
        /* The nominal lens puts the circle's edge degrees off: a loose first
         * round, then the matches re-judged in pixels with the lens solved. */
        double s = st.feat[0].scale > 0.0 ? st.feat[0].scale : 1.0;
        for (int p = 0; p < pairs; p++)
            if (res->pair[p].status == SL_STITCH_PAIR_SOLVED && st.feat[res->pair[p].a].scale > 0)
                s = st.feat[res->pair[p].a].scale;
        /* With the circles' centre, unless the overlaps alone disagree
         * with it: then all again from the same start without it. */
        size_t rot_bytes = (size_t)count * sizeof *st.rot,
               match_bytes = (size_t)st.match_count * sizeof *st.matches;
        double (*rot_start)[3][3] = pull ? malloc(rot_bytes) : NULL;
        solve_match *matches_start = pull ? malloc(match_bytes + 1) : NULL;
        sl_lens lens_start = lens;
        if (rot_start && matches_start) {
            memcpy(rot_start, st.rot, rot_bytes);
            memcpy(matches_start, st.matches, match_bytes);
        }
        adjust_rounds(&st, free_view, &lens, opt, pull, s);
        if (pull && !centre_agrees(&st, free_view, &lens, opt, pull)) {
            if (rot_start && matches_start) {
                memcpy(st.rot, rot_start, rot_bytes);
                memcpy(st.matches, matches_start, match_bytes);
                lens = lens_start;
                lens.cx = res->lens_nominal.cx;
                lens.cy = res->lens_nominal.cy;
                adjust_rounds(&st, free_view, &lens, opt, NULL, s);
                res->overlap_centre[0] = lens.cx;
                res->overlap_centre[1] = lens.cy;
            }
        }
        free(rot_start), free(matches_start);
        keep_agreeing_pairs(&st, KEEP_MIN_AGREE);
        measure(&st, &lens);
        drop_disagreeing_pairs(&st);
        res->pairs_solved = res->pairs_fallback = 0;
        for (int p = 0; p < pairs; p++) {
            res->pairs_solved += res->pair[p].status == SL_STITCH_PAIR_SOLVED;
            res->pairs_fallback += res->pair[p].fallback;
        }
    }
    res->seconds_adjust = sl_seconds() - t;
    if (opt->solve_vignette && res->pairs_solved > 0)
        solve_vignette(count, st.feat, st.rot, &lens, res);
    t = sl_seconds();
    if (opt->radiance_lens && res->vignette_solved && !res->lens_held &&
        count <= SL_STITCH_MAX_VIEWS)
        refine_by_radiance(&st, free_view, &lens);
    if (opt->radiance_poses && opt->solve_poses && res->vignette_solved)
        place_by_radiance(&st, &lens, group);
    res->seconds_radiance = sl_seconds() - t;
    res->lens = lens;
    for (int v = 0; v < count; v++) {
        sl_view_pose_from_matrix((const double (*)[3])st.rot[v], &res->pose[v]);
        views[v].lens = lens;
        views[v].pose = res->pose[v];
    }
done:
    for (int v = 0; st.feat && v < count; v++)
        solve_features_free(&st.feat[v]);
    free(st.feat), free(st.rot), free(st.rot_nominal), free(st.pair_rot), free(st.matches);
    free(free_view), free(group);
    res->seconds_total = sl_seconds() - start;
    return r;
}
