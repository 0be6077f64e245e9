/* SPDX-License-Identifier: BSD-3-Clause */
/* HTML reports: a page built in memory, images as PNG and plots as SVG
 * beside it, the page written atomically at the end. */
#include "setlight/core.h"

#include <ctype.h>
#include <math.h>
#include <stdint.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#define REPORT_MIN_WIDTH 256

struct sl_report {
    char dir[2048];
    char name[256];
    sl_text html; /* html.failed: out of memory while building, finish reports it */
    int table_columns;
    size_t top;       /* where the summary goes: after the title and intro */
    size_t top_start; /* start of the summary being written, or SIZE_MAX */
    bool sectioned;   /* a section has begun: the summary's place is fixed */
};

static void append(sl_report *rep, const char *s, size_t n) { sl_text_add(&rep->html, s, n); }

/* lit must be a string literal (the "" makes anything else a compile error). */
#define append_lit(rep, lit) append((rep), "" lit, sizeof("" lit) - 1)

#define appendf(rep, ...) ((void)sl_text_printf(&(rep)->html, __VA_ARGS__))

static void append_escaped(sl_report *rep, const char *s)
{
    for (; *s; s++) {
        switch (*s) {
        case '<': append_lit(rep, "&lt;"); break;
        case '>': append_lit(rep, "&gt;"); break;
        case '&': append_lit(rep, "&amp;"); break;
        case '"': append_lit(rep, "&quot;"); break;
        default: append(rep, s, 1);
        }
    }
}

sl_result sl_report_new(sl_report **out, const char *dir, const char *name, const char *title,
                        sl_error *err)
{
    static const char head1[] = "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>";
    static const char head2[] =
        "</title>\n<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;"
        "color:#222}table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid "
        "#bbb;padding:3px 8px;text-align:right}th{background:#eee}figure{display:"
        "inline-block;margin:0.5em}img{max-width:512px}"
        "figcaption{font-size:90%;color:#555}</style></head><body>\n<h1>";
    *out = NULL;
    sl_report *rep = calloc(1, sizeof *rep);
    if (!rep)
        return sl_error_set(err, SL_ERR_NOMEM, "out of memory for a report");
    snprintf(rep->dir, sizeof rep->dir, "%s", dir);
    snprintf(rep->name, sizeof rep->name, "%s", name);
    append(rep, head1, sizeof head1 - 1);
    append_escaped(rep, title);
    append(rep, head2, sizeof head2 - 1);
    append_escaped(rep, title);
    append_lit(rep, "</h1>\n");
    rep->top = rep->html.len;
    rep->top_start = SIZE_MAX;
    if (rep->html.failed) {
        sl_report_free(rep);
        return sl_error_set(err, SL_ERR_NOMEM, "out of memory for a report");
    }
    *out = rep;
    return SL_OK;
}

void sl_report_free(sl_report *rep)
{
    if (!rep)
        return;
    sl_text_free(&rep->html);
    free(rep);
}

sl_result sl_report_finish(sl_report *rep, sl_error *err)
{
    static const char tail[] = "</body></html>\n";
    append(rep, tail, sizeof tail - 1);
    sl_result r;
    if (rep->html.failed)
        r = sl_error_set(err, SL_ERR_NOMEM, "out of memory while building the report");
    else {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s.html", rep->dir, rep->name);
        r = sl_write_file_atomic(path, rep->html.s, rep->html.len, err);
    }
    sl_report_free(rep);
    return r;
}

void sl_report_top_begin(sl_report *rep) { rep->top_start = rep->html.len; }

void sl_report_top_end(sl_report *rep)
{
    if (rep->html.failed || rep->top_start == SIZE_MAX || rep->top_start < rep->top)
        return;
    size_t n = rep->html.len - rep->top_start;
    char *chunk = malloc(n + 1);
    if (!chunk) {
        rep->html.failed = true;
        return;
    }
    memcpy(chunk, rep->html.s + rep->top_start, n);
    memmove(rep->html.s + rep->top + n, rep->html.s + rep->top, rep->top_start - rep->top);
    memcpy(rep->html.s + rep->top, chunk, n);
    free(chunk);
    rep->top += n;
    rep->top_start = SIZE_MAX;
}

void sl_report_section(sl_report *rep, const char *title)
{
    /* the summary goes after the title and the text before the first section */
    if (!rep->sectioned && rep->top_start == SIZE_MAX)
        rep->top = rep->html.len;
    rep->sectioned = true;
    append_lit(rep, "<h2>");
    append_escaped(rep, title);
    append_lit(rep, "</h2>\n");
}

void sl_report_text(sl_report *rep, const char *fmt, ...)
{
    char buf[4096];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    append_lit(rep, "<p>");
    append_escaped(rep, buf);
    append_lit(rep, "</p>\n");
}

/* A relative file name as a URL in an attribute: every byte but the
 * unreserved ones and '/' percent-encoded, so a setup named "a#1" or
 * "b?c" (legal folder names) still links to its picture. */
static void append_url(sl_report *rep, const char *file)
{
    static const char hex[] = "0123456789ABCDEF";
    for (const unsigned char *c = (const unsigned char *)file; *c; c++) {
        if (isalnum(*c) || strchr("-._~/", *c))
            append(rep, (const char *)c, 1);
        else
            appendf(rep, "%%%c%c", hex[*c >> 4], hex[*c & 15]);
    }
}

/* "<figure><img src=FILE><figcaption>CAPTION</figcaption>", left open for
 * more captions. */
static void figure_begin(sl_report *rep, const char *file, const char *caption)
{
    append_lit(rep, "<figure><img src=\"");
    append_url(rep, file);
    append_lit(rep, "\"><figcaption>");
    append_escaped(rep, caption);
    append_lit(rep, "</figcaption>");
}

sl_result sl_report_image(sl_report *rep, const char *file, const sl_image *img, double stops,
                          const char *caption, sl_error *err)
{
    /* Small images are enlarged (whole pixels, no blur) so a person can
     * judge them: at least REPORT_MIN_WIDTH wide. */
    int k = img->width > 0 && img->width < REPORT_MIN_WIDTH
                ? (REPORT_MIN_WIDTH + img->width - 1) / img->width
                : 1;
    sl_image big = {0};
    if (k > 1) {
        sl_result ra = sl_image_alloc(&big, img->width * k, img->height * k, img->channels, err);
        if (ra)
            return ra;
        for (int y = 0; y < big.height; y++)
            for (int x = 0; x < big.width; x++)
                memcpy(sl_image_pixel(&big, x, y), sl_image_pixel(img, x / k, y / k),
                       sizeof(float) * (size_t)img->channels);
    }
    /* The same picture as a convert preview at that exposure (default view). */
    sl_preview_options opt = {.exposure_stops = stops};
    sl_preview_result shown;
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", rep->dir, file);
    sl_result r = sl_preview_write(path, k > 1 ? &big : img, NULL, &opt, &shown, err);
    sl_image_free(&big);
    if (r)
        return r;
    figure_begin(rep, file, caption ? caption : file);
    append_lit(rep, "</figure>\n");
    return SL_OK;
}

void sl_report_figure(sl_report *rep, const char *file, int width, const char *caption)
{
    append_lit(rep, "<figure><img src=\"");
    append_url(rep, file);
    if (width > 0)
        appendf(rep, "\" width=\"%d", width);
    append_lit(rep, "\"><figcaption>");
    append_escaped(rep, caption ? caption : file);
    append_lit(rep, "</figcaption></figure>\n");
}

void sl_report_link(sl_report *rep, const char *file, const char *text)
{
    append_lit(rep, "<p><a href=\"");
    append_url(rep, file);
    append_lit(rep, "\">");
    append_escaped(rep, text);
    append_lit(rep, "</a></p>\n");
}

void sl_report_table_begin(sl_report *rep, int columns, const char *const *header)
{
    append_lit(rep, "<table><tr>");
    for (int i = 0; i < columns; i++) {
        append_lit(rep, "<th>");
        append_escaped(rep, header[i]);
        append_lit(rep, "</th>");
    }
    append_lit(rep, "</tr>\n");
    rep->table_columns = columns;
}

void sl_report_table_row(sl_report *rep, const char *const *cells)
{
    append_lit(rep, "<tr>");
    for (int i = 0; i < rep->table_columns; i++) {
        append_lit(rep, "<td>");
        append_escaped(rep, cells[i] ? cells[i] : "");
        append_lit(rep, "</td>");
    }
    append_lit(rep, "</tr>\n");
}

void sl_report_table_end(sl_report *rep) { append_lit(rep, "</table>\n"); }

/* --- SVG plots -------------------------------------------------------- */

static bool plottable(double v, bool log_axis) { return isfinite(v) && (!log_axis || v > 0); }

static double axis_map(double v, double lo, double hi, bool log_axis)
{
    if (log_axis) {
        v = log10(v);
        lo = log10(lo);
        hi = log10(hi);
    }
    return hi > lo ? (v - lo) / (hi - lo) : 0.5;
}

static void svg_build(sl_report *svg, const char *title, const char *xlabel, const char *ylabel,
                      bool log_x, bool log_y, const sl_plot_series *series, int n)
{
    static const char *const colours[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e",
                                          "#9467bd", "#8c564b", "#e377c2", "#17becf"};
    const double W = 640, H = 420, L = 70, R = 170, T = 40, B = 50;
    double xlo = INFINITY, xhi = -INFINITY, ylo = INFINITY, yhi = -INFINITY;
    for (int s = 0; s < n; s++)
        for (int i = 0; i < series[s].count; i++) {
            double x = series[s].x[i], y = series[s].y[i];
            if (!plottable(x, log_x) || !plottable(y, log_y))
                continue;
            xlo = fmin(xlo, x), xhi = fmax(xhi, x), ylo = fmin(ylo, y), yhi = fmax(yhi, y);
        }
    if (!(xlo <= xhi)) {
        xlo = 1, xhi = 10, ylo = 1, yhi = 10;
    }
    if (log_x) {
        xlo = pow(10, floor(log10(xlo))), xhi = pow(10, ceil(log10(xhi)));
    }
    if (log_y) {
        ylo = pow(10, floor(log10(ylo))), yhi = pow(10, ceil(log10(yhi)));
    }
    if (xlo == xhi)
        xhi = xlo + 1;
    if (ylo == yhi)
        yhi = ylo + 1;
    double pw = W - L - R, ph = H - T - B;
    appendf(svg, "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%g\" height=\"%g\" "
                 "font-family=\"sans-serif\" font-size=\"12\">\n", W, H);
    appendf(svg, "<rect x=\"%g\" y=\"%g\" width=\"%g\" height=\"%g\" fill=\"none\" "
                 "stroke=\"#444\"/>\n", L, T, pw, ph);
    appendf(svg, "<text x=\"%g\" y=\"24\" text-anchor=\"middle\" font-size=\"14\">", L + pw / 2);
    append_escaped(svg, title);
    append_lit(svg, "</text>\n");
    appendf(svg, "<text x=\"%g\" y=\"%g\" text-anchor=\"middle\">", L + pw / 2, H - 10);
    append_escaped(svg, xlabel);
    append_lit(svg, "</text>\n");
    appendf(svg, "<text x=\"16\" y=\"%g\" text-anchor=\"middle\" transform=\"rotate(-90 16 %g)\">",
            T + ph / 2, T + ph / 2);
    append_escaped(svg, ylabel);
    append_lit(svg, "</text>\n");
    /* ticks: decades on log axes, 5 divisions on linear ones */
    for (int axis = 0; axis < 2; axis++) {
        bool lg = axis ? log_y : log_x;
        double lo = axis ? ylo : xlo, hi = axis ? yhi : xhi;
        int steps = lg ? (int)lround(log10(hi) - log10(lo)) : 5;
        if (steps < 1)
            steps = 1;
        if (steps > 12)
            steps = 12;
        for (int k = 0; k <= steps; k++) {
            double v = lg ? pow(10, log10(lo) + (log10(hi) - log10(lo)) * k / steps)
                          : lo + (hi - lo) * k / steps;
            double t = axis_map(v, lo, hi, lg);
            if (axis == 0)
                appendf(svg, "<line x1=\"%.1f\" y1=\"%g\" x2=\"%.1f\" y2=\"%g\" stroke=\"#ddd\"/>"
                             "<text x=\"%.1f\" y=\"%g\" text-anchor=\"middle\">%.3g</text>\n",
                        L + t * pw, T, L + t * pw, T + ph, L + t * pw, T + ph + 16, v);
            else
                appendf(svg, "<line x1=\"%g\" y1=\"%.1f\" x2=\"%g\" y2=\"%.1f\" stroke=\"#ddd\"/>"
                             "<text x=\"%g\" y=\"%.1f\" text-anchor=\"end\">%.3g</text>\n",
                        L, T + (1 - t) * ph, L + pw, T + (1 - t) * ph, L - 4, T + (1 - t) * ph + 4, v);
        }
    }
    for (int s = 0; s < n; s++) {
        const char *colour = colours[s % 8];
        appendf(svg, "<polyline fill=\"none\" stroke-width=\"2\" stroke=\"%s\" points=\"", colour);
        for (int i = 0; i < series[s].count; i++) {
            double x = series[s].x[i], y = series[s].y[i];
            if (!plottable(x, log_x) || !plottable(y, log_y))
                continue;
            appendf(svg, "%.1f,%.1f ", L + axis_map(x, xlo, xhi, log_x) * pw,
                    T + (1 - axis_map(y, ylo, yhi, log_y)) * ph);
        }
        append_lit(svg, "\"/>\n");
        appendf(svg, "<line x1=\"%g\" y1=\"%g\" x2=\"%g\" y2=\"%g\" stroke=\"%s\" stroke-width=\"2\"/>"
                     "<text x=\"%g\" y=\"%g\">", W - R + 10, T + 10 + 18.0 * s, W - R + 30,
                T + 10 + 18.0 * s, colour, W - R + 36, T + 14 + 18.0 * s);
        append_escaped(svg, series[s].label ? series[s].label : "");
        append_lit(svg, "</text>\n");
    }
    append_lit(svg, "</svg>\n");
}

/* Writes a built SVG atomically and frees it. */
static sl_result svg_write(sl_report *svg, const char *path, sl_error *err)
{
    sl_result r = svg->html.failed ? sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path)
                                   : sl_write_file_atomic(path, svg->html.s, svg->html.len, err);
    sl_text_free(&svg->html);
    return r;
}

sl_result sl_plot_write_svg(const char *path, const char *title, const char *xlabel,
                            const char *ylabel, bool log_x, bool log_y,
                            const sl_plot_series *series, int series_count, sl_error *err)
{
    sl_report svg;
    memset(&svg, 0, sizeof svg);
    svg_build(&svg, title, xlabel, ylabel, log_x, log_y, series, series_count);
    return svg_write(&svg, path, err);
}

sl_result sl_report_plot(sl_report *rep, const char *file, const char *title, const char *xlabel,
                         const char *ylabel, bool log_x, bool log_y, const sl_plot_series *series,
                         int series_count, sl_error *err)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", rep->dir, file);
    sl_result r = sl_plot_write_svg(path, title, xlabel, ylabel, log_x, log_y, series,
                                    series_count, err);
    if (r)
        return r;
    figure_begin(rep, file, title);
    append_lit(rep, "</figure>\n");
    return SL_OK;
}

/* --- SVG bar charts ----------------------------------------------------- */

static void svg_bars(sl_report *svg, const char *title, const char *ylabel,
                     const char *const *labels, const char *const *notes, int count,
                     const sl_bar_series *series, int n)
{
    static const char *const colours[] = {"#9aa7b4", "#1f77b4", "#d62728", "#2ca02c"};
    const double L = 60, R = 150, T = 40, B = 70, ph = 300;
    double group = n * 10.0 + 8, pw = group * count, W = L + pw + R, H = T + ph + B;
    double hi = 0;
    for (int s = 0; s < n; s++)
        for (int i = 0; i < count; i++)
            if (isfinite(series[s].values[i]) && series[s].values[i] > hi)
                hi = series[s].values[i];
    /* a round top: 1, 2 or 5 times a power of ten */
    double step = hi > 0 ? pow(10, floor(log10(hi / 5))) : 1;
    while (hi / step > 5)
        step *= hi / step > 10 ? 5 : 2;
    double top = step * ceil((hi > 0 ? hi : 1) / step);
    appendf(svg, "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%g\" height=\"%g\" "
                 "font-family=\"sans-serif\" font-size=\"12\">\n", W, H);
    appendf(svg, "<text x=\"%g\" y=\"24\" text-anchor=\"middle\" font-size=\"14\">", L + pw / 2);
    append_escaped(svg, title);
    append_lit(svg, "</text>\n");
    appendf(svg, "<text x=\"16\" y=\"%g\" text-anchor=\"middle\" transform=\"rotate(-90 16 %g)\">",
            T + ph / 2, T + ph / 2);
    append_escaped(svg, ylabel);
    append_lit(svg, "</text>\n");
    for (double v = 0; v <= top * (1 + 1e-9); v += step) {
        double y = T + ph * (1 - v / top);
        appendf(svg, "<line x1=\"%g\" y1=\"%.1f\" x2=\"%g\" y2=\"%.1f\" stroke=\"#ddd\"/>"
                     "<text x=\"%g\" y=\"%.1f\" text-anchor=\"end\">%.3g</text>\n",
                L, y, L + pw, y, L - 4, y + 4, v);
    }
    for (int i = 0; i < count; i++) {
        double x0 = L + group * i + 4;
        bool excluded = notes && notes[i] && notes[i][0];
        for (int s = 0; s < n; s++) {
            double v = series[s].values[i];
            if (!isfinite(v) || v < 0)
                continue;
            double h = ph * fmin(v, top) / top;
            appendf(svg, "<rect x=\"%.1f\" y=\"%.1f\" width=\"9\" height=\"%.1f\" fill=\"%s\"%s>"
                         "<title>",
                    x0 + 10.0 * s, T + ph - h, h, colours[s % 4],
                    excluded ? " fill-opacity=\"0.35\"" : "");
            append_escaped(svg, labels[i]);
            appendf(svg, ": %.3g", v);
            append_lit(svg, "</title></rect>\n");
        }
        double cx = x0 + 5.0 * n;
        appendf(svg, "<text x=\"%.1f\" y=\"%g\" text-anchor=\"end\" transform=\"rotate(-60 %.1f %g)\"%s>",
                cx, T + ph + 12, cx, T + ph + 12, excluded ? " fill=\"#a00\"" : "");
        append_escaped(svg, labels[i]);
        if (excluded)
            append_lit(svg, " \xc3\x97"); /* a multiplication sign marks it excluded */
        append_lit(svg, "</text>\n");
    }
    appendf(svg, "<line x1=\"%g\" y1=\"%g\" x2=\"%g\" y2=\"%g\" stroke=\"#444\"/>\n", L, T + ph,
            L + pw, T + ph);
    for (int s = 0; s < n; s++) {
        appendf(svg, "<rect x=\"%g\" y=\"%g\" width=\"12\" height=\"12\" fill=\"%s\"/>"
                     "<text x=\"%g\" y=\"%g\">",
                W - R + 10, T + 18.0 * s, colours[s % 4], W - R + 28, T + 10 + 18.0 * s);
        append_escaped(svg, series[s].label ? series[s].label : "");
        append_lit(svg, "</text>\n");
    }
    if (notes)
        for (int i = 0; i < count; i++)
            if (notes[i] && notes[i][0]) {
                appendf(svg, "<text x=\"%g\" y=\"%g\" fill=\"#a00\">\xc3\x97 excluded</text>\n",
                        W - R + 10, T + 18.0 * n + 6);
                break;
            }
    append_lit(svg, "</svg>\n");
}

sl_result sl_report_bars(sl_report *rep, const char *file, const char *title, const char *ylabel,
                         const char *const *labels, const char *const *notes, int count,
                         const sl_bar_series *series, int series_count, sl_error *err)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", rep->dir, file);
    sl_report svg;
    memset(&svg, 0, sizeof svg);
    svg_bars(&svg, title, ylabel, labels, notes, count, series, series_count);
    sl_result r = svg_write(&svg, path, err);
    if (r)
        return r;
    figure_begin(rep, file, title);
    /* the excluded entries and why, beside the chart */
    bool any = false;
    for (int i = 0; notes && i < count; i++)
        if (notes[i] && notes[i][0]) {
            if (any)
                append_lit(rep, "<br>");
            else
                append_lit(rep, "<figcaption>Excluded: ");
            append_escaped(rep, labels[i]);
            append_lit(rep, ": ");
            append_escaped(rep, notes[i]);
            any = true;
        }
    if (any)
        append_lit(rep, "</figcaption>");
    append_lit(rep, "</figure>\n");
    return SL_OK;
}
