/* SPDX-License-Identifier: BSD-3-Clause */
/* HTML reports and SVG plots: content escaped, files written atomically,
 * images written as PNG beside the page. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "testing.h"

static void test_report_page(void)
{
    sl_report *rep;
    sl_error err;
    CHECK_OK(sl_report_new(&rep, sl_test_tmpdir(), "report", "Demo <stage>", &err), &err);
    sl_report_section(rep, "Merge & unwrap");
    sl_report_text(rep, "median error %.2f%% in %.1f s", 0.8, 1.5);
    const char *head[3] = {"stage", "error", "seconds"};
    const char *row[3] = {"merge", "0.8%", "<1"};
    sl_report_table_begin(rep, 3, head);
    sl_report_table_row(rep, row);
    sl_report_table_end(rep);
    double x[4] = {0.1, 1, 10, 100}, y1[4] = {1, 0.3, 0.1, 0.03}, y2[4] = {2, 0.5, 0, 0.05};
    sl_plot_series s[2] = {{"MIS", x, y1, 4}, {"BSDF only", x, y2, 4}};
    CHECK_OK(sl_report_plot(rep, "conv.svg", "error vs time", "seconds", "relative RMSE", true,
                            true, s, 2, &err),
             &err);
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 8, 4, 3, &err), &err);
    sl_image_fill(&img, 0.18f);
    CHECK_OK(sl_report_image(rep, "grey.png", &img, 1.0, "grey at +1 stop", &err), &err);
    sl_image_free(&img);
    /* a setup folder may be named anything: its picture's URL is encoded */
    sl_report_figure(rep, "a#1 b?c/report_latlong.png", 256, "a#1 b?c");
    sl_report_link(rep, "a#1 b?c/report.html", "the setup's <report>");
    CHECK_OK(sl_report_finish(rep, &err), &err);

    char *html = sl_test_read_file(sl_test_path("report.html"), NULL);
    CHECK(html != NULL);
    if (html) {
        CHECK(strstr(html, "Demo &lt;stage&gt;") != NULL);
        CHECK(strstr(html, "Merge &amp; unwrap") != NULL);
        CHECK(strstr(html, "<td>&lt;1</td>") != NULL);
        CHECK(strstr(html, "src=\"conv.svg\"") != NULL);
        CHECK(strstr(html, "src=\"grey.png\"") != NULL);
        CHECK(strstr(html, "src=\"a%231%20b%3Fc/report_latlong.png\" width=\"256\"") != NULL);
        CHECK(strstr(html, "<figcaption>a#1 b?c</figcaption>") != NULL);
        CHECK(strstr(html, "<a href=\"a%231%20b%3Fc/report.html\">the setup's &lt;report&gt;</a>") !=
              NULL);
        CHECK(strstr(html, "</html>") != NULL);
        free(html);
    }
    char *svg = sl_test_read_file(sl_test_path("conv.svg"), NULL);
    CHECK(svg != NULL);
    if (svg) {
        CHECK(strstr(svg, "<svg") != NULL && strstr(svg, "</svg>") != NULL);
        CHECK(strstr(svg, "BSDF only") != NULL);
        /* two series: two polylines; the zero on a log axis is skipped, not NaN */
        CHECK(strstr(svg, "nan") == NULL);
        int lines = 0;
        for (const char *p = svg; (p = strstr(p, "<polyline")); p++)
            lines++;
        CHECK(lines == 2);
        free(svg);
    }
    sl_image back;
    sl_meta meta;
    CHECK_OK(sl_image_read(sl_test_path("grey.png"), &back, &meta, &err), &err);
    /* 0.18 * 2 = 0.36 linear -> sRGB 0.63424 -> 162/255 */
    CHECK_NEAR(sl_image_pixel(&back, 3, 2)[1], 162.0 / 255.0, 0.5 / 255.0);
    /* the 8 px image is enlarged by whole pixels to at least 256 px */
    CHECK(back.width == 256 && back.height == 128);
    sl_image_free(&back);
    sl_meta_free(&meta);
}

/* The summary written last stands first, right after the title; a bar chart
 * marks its excluded entries and lists why beside it. */
static void test_report_summary_and_bars(void)
{
    sl_report *rep;
    sl_error err;
    CHECK_OK(sl_report_new(&rep, sl_test_tmpdir(), "bars", "Calibration", &err), &err);
    sl_report_text(rep, "intro");
    sl_report_section(rep, "Details");
    const char *labels[3] = {"dark skin", "white", "black"};
    const char *notes[3] = {NULL, "clipped in the photo", NULL};
    double before[3] = {4.5, 2.0, 7.25}, after[3] = {0.5, NAN, 1.0};
    sl_bar_series series[2] = {{"before", before}, {"after", after}};
    CHECK_OK(sl_report_bars(rep, "de.svg", "CIEDE2000 per patch", "dE00", labels, notes, 3,
                            series, 2, &err),
             &err);
    sl_report_top_begin(rep);
    sl_report_section(rep, "Summary");
    sl_report_text(rep, "mean dE00 4.6 -> 0.75");
    sl_report_top_end(rep);
    CHECK_OK(sl_report_finish(rep, &err), &err);
    char *html = sl_test_read_file(sl_test_path("bars.html"), NULL);
    CHECK(html != NULL);
    if (html) {
        const char *title = strstr(html, "<h1>"), *summary = strstr(html, "<h2>Summary");
        const char *details = strstr(html, "<h2>Details");
        const char *intro = strstr(html, "<p>intro");
        CHECK(title && intro && summary && details && title < intro && intro < summary &&
              summary < details);
        CHECK(strstr(html, "<figcaption>Excluded: white: clipped in the photo</figcaption>") !=
              NULL);
        CHECK(strstr(html, "</html>") != NULL);
        free(html);
    }
    char *svg = sl_test_read_file(sl_test_path("de.svg"), NULL);
    CHECK(svg != NULL);
    if (svg) {
        int bars = 0, faint = 0;
        for (const char *p = svg; (p = strstr(p, "<rect x=")); p++)
            bars++;
        for (const char *p = svg; (p = strstr(p, "fill-opacity")); p++)
            faint++;
        /* five bars (the NaN has none) and two legend boxes; the excluded
         * patch's one bar drawn faint */
        CHECK_MSG(bars == 7, "%d rects", bars);
        CHECK(faint == 1);
        CHECK(strstr(svg, "nan") == NULL && strstr(svg, "white") != NULL);
        free(svg);
    }
}

static void test_report_bad_dir(void)
{
    sl_report *rep;
    sl_error err;
    CHECK_OK(sl_report_new(&rep, sl_test_path("no/such/dir"), "report", "x", &err), &err);
    CHECK_RESULT(sl_report_finish(rep, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "report.html") != NULL);
}

int main(void)
{
    RUN(test_report_page);
    RUN(test_report_bad_dir);
    RUN(test_report_summary_and_bars);
    return sl_test_finish();
}
