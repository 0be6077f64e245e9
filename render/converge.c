/* SPDX-License-Identifier: BSD-3-Clause */
/* Convergence reports: each sampling strategy rendered against one
 * reference, error per pass, a table and an SVG log-log plot. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/render.h"

/* The last one is not a sampler: the closed form (exact, control variate
 * or sampled per pixel), when the options allow it. */
static const struct {
    const char *name;
    sl_strategy strategy;
    bool ld, closed_form;
} configs[] = {
    {"uniform", SL_STRATEGY_UNIFORM, false, false}, {"cosine", SL_STRATEGY_COSINE, false, false},
    {"bsdf", SL_STRATEGY_BSDF, false, false},       {"light", SL_STRATEGY_LIGHT, false, false},
    {"mis", SL_STRATEGY_MIS, false, false},         {"mis+sobol", SL_STRATEGY_MIS, true, false},
    {"closed-form", SL_STRATEGY_MIS, true, true},
};

void sl_converge_report_free(sl_converge_report *rep)
{
    for (int i = 0; i < rep->count; i++)
        sl_render_stats_free(&rep->curves[i].stats);
    memset(rep, 0, sizeof *rep);
}

sl_result sl_converge_run(const sl_scene *scene, const sl_render_options *base,
                          const sl_image *reference, int64_t reference_spp,
                          sl_converge_report *rep, sl_error *err)
{
    memset(rep, 0, sizeof *rep);
    if (base->spp < 1)
        return sl_error_set(err, SL_ERR_USAGE, "converge: needs a sample budget (spp >= 1)");
    sl_image own = {0}, img = {0};
    sl_result r;
    if (!reference) {
        if (reference_spp < base->spp)
            return sl_error_set(err, SL_ERR_USAGE,
                                "converge: reference spp %lld must be at least the budget %lld",
                                (long long)reference_spp, (long long)base->spp);
        sl_render_options ro = *base;
        ro.spp = reference_spp;
        ro.strategy = SL_STRATEGY_MIS;
        ro.low_discrepancy = true;
        ro.seed = base->seed ^ 0x5eed5eedull; /* independent of the curves' samples */
        ro.reference = NULL;
        ro.time_limit = ro.target_error = 0;
        ro.closed_form = false; /* the curves compare sampling strategies */
        sl_render_stats st;
        if ((r = sl_render(scene, &ro, &own, &st, err)))
            return r;
        rep->reference_spp = st.spp;
        rep->reference_seconds = st.seconds;
        sl_render_stats_free(&st);
        reference = &own;
    }
    for (size_t i = 0; i < sizeof configs / sizeof configs[0]; i++) {
        if (configs[i].closed_form && !base->closed_form)
            continue;
        sl_converge_curve *c = &rep->curves[rep->count];
        sl_render_options o = *base;
        o.strategy = configs[i].strategy;
        o.low_discrepancy = configs[i].ld;
        o.reference = reference;
        o.time_limit = o.target_error = 0;
        o.closed_form = configs[i].closed_form;
        snprintf(c->name, sizeof c->name, "%s", configs[i].name);
        c->strategy = o.strategy;
        c->low_discrepancy = o.low_discrepancy;
        if ((r = sl_render(scene, &o, &img, &c->stats, err))) {
            sl_converge_report_free(rep);
            sl_image_free(&own);
            return r;
        }
        sl_image_free(&img);
        rep->count++;
    }
    sl_image_free(&own);
    return SL_OK;
}

static double to_reach(const sl_converge_curve *c, double target, bool seconds)
{
    const sl_render_pass *p = c->stats.passes;
    for (int i = 0; i < c->stats.pass_count; i++) {
        if (!(p[i].ref_rel_rmse <= target))
            continue;
        double x1 = seconds ? p[i].seconds : (double)p[i].spp;
        if (i == 0 || !(p[i - 1].ref_rel_rmse > 0) || !(p[i].ref_rel_rmse > 0))
            return x1;
        double x0 = seconds ? p[i - 1].seconds : (double)p[i - 1].spp;
        if (!(x0 > 0))
            return x1;
        double e0 = log(p[i - 1].ref_rel_rmse), e1 = log(p[i].ref_rel_rmse), et = log(target);
        double f = e0 != e1 ? (e0 - et) / (e0 - e1) : 1.0;
        return exp(log(x0) + f * (log(x1) - log(x0)));
    }
    return -1;
}

double sl_converge_spp_to_reach(const sl_converge_curve *c, double target)
{
    return to_reach(c, target, false);
}

double sl_converge_seconds_to_reach(const sl_converge_curve *c, double target)
{
    return to_reach(c, target, true);
}

/* A growing text buffer. */
typedef struct buf {
    char *s;
    size_t n, cap;
    bool failed;
} buf;

static void bprintf(buf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void bprintf(buf *b, const char *fmt, ...)
{
    va_list ap;
    for (;;) {
        size_t room = b->cap - b->n;
        va_start(ap, fmt);
        int k = b->s ? vsnprintf(b->s + b->n, room, fmt, ap) : -1;
        va_end(ap);
        if (k >= 0 && (size_t)k < room) {
            b->n += (size_t)k;
            return;
        }
        size_t cap = b->cap ? b->cap * 2 : 4096;
        while (k >= 0 && cap < b->n + (size_t)k + 1)
            cap *= 2;
        char *ns = realloc(b->s, cap);
        if (!ns) {
            b->failed = true;
            return;
        }
        b->s = ns, b->cap = cap;
    }
}

static sl_result flush(buf *b, const char *path, sl_error *err)
{
    sl_result r = b->failed ? sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path)
                            : sl_write_file_atomic(path, b->s, b->n, err);
    free(b->s);
    return r;
}

sl_result sl_converge_write_table(const sl_converge_report *rep, double target, const char *path,
                                  sl_error *err)
{
    buf b = {0};
    bprintf(&b, "| strategy | spp | seconds | samples/s | rel. RMSE | spp to %.3g | seconds to %.3g |\n",
            target, target);
    bprintf(&b, "|---|---:|---:|---:|---:|---:|---:|\n");
    for (int i = 0; i < rep->count; i++) {
        const sl_converge_curve *c = &rep->curves[i];
        const sl_render_pass *last = c->stats.pass_count ? &c->stats.passes[c->stats.pass_count - 1] : NULL;
        double ns = sl_converge_spp_to_reach(c, target), ts = sl_converge_seconds_to_reach(c, target);
        bprintf(&b, "| %s | %lld | %.4g | %.4g | %.4g | ", c->name, (long long)c->stats.spp,
                c->stats.seconds, c->stats.samples_per_second, last ? last->ref_rel_rmse : -1.0);
        if (ns > 0)
            bprintf(&b, "%.4g | %.4g |\n", ns, ts);
        else
            bprintf(&b, "not reached | not reached |\n");
    }
    if (rep->reference_spp)
        bprintf(&b, "\nReference: mis+sobol, %lld spp, %.4g s.\n", (long long)rep->reference_spp,
                rep->reference_seconds);
    return flush(&b, path, err);
}

sl_result sl_converge_write_svg(const sl_converge_report *rep, const char *path, sl_error *err)
{
    static const char *const colours[] = {"#888888", "#1f77b4", "#ff7f0e", "#2ca02c",
                                          "#9467bd", "#d62728", "#8c564b", "#e377c2"};
    double tmin = INFINITY, tmax = 0, emin = INFINITY, emax = 0;
    for (int i = 0; i < rep->count; i++)
        for (int k = 0; k < rep->curves[i].stats.pass_count; k++) {
            const sl_render_pass *p = &rep->curves[i].stats.passes[k];
            if (p->seconds > 0 && p->ref_rel_rmse > 0) {
                tmin = fmin(tmin, p->seconds), tmax = fmax(tmax, p->seconds);
                emin = fmin(emin, p->ref_rel_rmse), emax = fmax(emax, p->ref_rel_rmse);
            }
        }
    if (!(tmax > 0) || !(emax > 0))
        return sl_error_set(err, SL_ERR_INPUT, "%s: no error measurements to plot", path);
    /* whole decades around the data */
    double lt0 = floor(log10(tmin)), lt1 = ceil(log10(tmax)), le0 = floor(log10(emin)),
           le1 = ceil(log10(emax));
    if (lt1 <= lt0)
        lt1 = lt0 + 1;
    if (le1 <= le0)
        le1 = le0 + 1;
    const double W = 640, H = 440, L = 70, R = 150, T = 20, B = 50;
    buf b = {0};
    bprintf(&b,
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%g\" height=\"%g\" "
            "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%%\" height=\"100%%\" "
            "fill=\"white\"/>\n",
            W, H);
#define PX(t) (L + (log10(t) - lt0) / (lt1 - lt0) * (W - L - R))
#define PY(e) (T + (le1 - log10(e)) / (le1 - le0) * (H - T - B))
    for (double d = lt0; d <= lt1 + 1e-9; d++)
        bprintf(&b,
                "<line x1=\"%.1f\" y1=\"%g\" x2=\"%.1f\" y2=\"%g\" stroke=\"#ddd\"/><text "
                "x=\"%.1f\" y=\"%g\" text-anchor=\"middle\">1e%g s</text>\n",
                PX(pow(10, d)), T, PX(pow(10, d)), H - B, PX(pow(10, d)), H - B + 16, d);
    for (double d = le0; d <= le1 + 1e-9; d++)
        bprintf(&b,
                "<line x1=\"%g\" y1=\"%.1f\" x2=\"%g\" y2=\"%.1f\" stroke=\"#ddd\"/><text "
                "x=\"%g\" y=\"%.1f\" text-anchor=\"end\">1e%g</text>\n",
                L, PY(pow(10, d)), W - R, PY(pow(10, d)), L - 6, PY(pow(10, d)) + 4, d);
    bprintf(&b,
            "<text x=\"%g\" y=\"%g\" text-anchor=\"middle\">wall time (s)</text>\n<text x=\"14\" "
            "y=\"%g\" transform=\"rotate(-90 14 %g)\" text-anchor=\"middle\">relative RMSE</text>\n",
            L + (W - L - R) / 2, H - 12, T + (H - T - B) / 2, T + (H - T - B) / 2);
    for (int i = 0; i < rep->count; i++) {
        const sl_converge_curve *c = &rep->curves[i];
        const char *col = colours[i % 8];
        bprintf(&b, "<polyline fill=\"none\" stroke=\"%s\" stroke-width=\"2\" points=\"", col);
        for (int k = 0; k < c->stats.pass_count; k++) {
            const sl_render_pass *p = &c->stats.passes[k];
            if (p->seconds > 0 && p->ref_rel_rmse > 0)
                bprintf(&b, "%.1f,%.1f ", PX(p->seconds), PY(p->ref_rel_rmse));
        }
        bprintf(&b, "\"/>\n<text x=\"%g\" y=\"%g\" fill=\"%s\">%s</text>\n", W - R + 10,
                T + 16 + 18 * i, col, c->name);
    }
#undef PX
#undef PY
    bprintf(&b, "</svg>\n");
    return flush(&b, path, err);
}
