/* SPDX-License-Identifier: BSD-3-Clause */
#include "testing.h"

#include <dirent.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int sl_test_passed;
int sl_test_failed;
int sl_test_skipped;

void sl_test_fail(const char *file, int line, const char *fmt, ...)
{
    va_list ap;
    sl_test_failed++;
    fprintf(stdout, "%s:%d: FAILED: ", file, line);
    va_start(ap, fmt);
    vfprintf(stdout, fmt, ap);
    va_end(ap);
    fputc('\n', stdout);
    fflush(stdout);
}

static char tmpdir[4096];

const char *sl_test_tmpdir(void)
{
    if (tmpdir[0])
        return tmpdir;
    char exe[256] = "test";
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n > 0) {
        exe[n] = 0;
        char *slash = strrchr(exe, '/');
        if (slash)
            memmove(exe, slash + 1, strlen(slash));
    }
    mkdir(SETLIGHT_TEST_TMP, 0755);
    snprintf(tmpdir, sizeof tmpdir, "%.3800s/%.255s", SETLIGHT_TEST_TMP, exe);
    char cmd[4200];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0)
        fprintf(stderr, "warning: could not clear %s\n", tmpdir);
    mkdir(tmpdir, 0755);
    return tmpdir;
}

const char *sl_test_path(const char *name)
{
    static char buf[8][4096];
    static int next;
    char *b = buf[next++ & 7];
    snprintf(b, 4096, "%.3000s/%.1000s", sl_test_tmpdir(), name);
    return b;
}

void sl_test_skip(const char *what)
{
    sl_test_skipped++;
    printf("skip %s\n", what);
}

const char *sl_test_data(const char *relative)
{
    static char buf[8][4096];
    static int next;
    const char *root = getenv("SETLIGHT_SHARED_DATA");
    if (!root || !*root)
        root = SETLIGHT_SHARED_DATA;
    char *b = buf[next++ & 7];
    snprintf(b, 4096, "%.3000s/%.1000s", root, relative);
    struct stat st;
    if (stat(b, &st) != 0) {
        char msg[4200];
        snprintf(msg, sizeof msg, "shared data %s absent", relative);
        sl_test_skip(msg);
        return NULL;
    }
    return b;
}

bool sl_test_sanitized(void)
{
#if defined(__SANITIZE_ADDRESS__)
    return true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
    return true;
#endif
#endif
    const char *s = getenv("SETLIGHT_SANITIZED");
    return s && *s && strcmp(s, "0") != 0;
}

bool sl_test_file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

int sl_test_count_files(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, ".."))
            n++;
    closedir(d);
    return n;
}

char *sl_test_read_file(const char *path, size_t *size)
{
    if (size)
        *size = 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *s = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (s && fread(s, 1, (size_t)n, f) != (size_t)n) {
        free(s);
        s = NULL;
    }
    fclose(f);
    if (s) {
        s[n] = 0;
        if (size)
            *size = (size_t)n;
    }
    return s;
}

uint64_t sl_test_rand(uint64_t *state)
{
    return sl_splitmix64(state);
}

double sl_test_uniform(uint64_t *state)
{
    return (double)(sl_test_rand(state) >> 11) * 0x1.0p-53;
}

void sl_test_shuffle(int *a, int n, uint64_t *state)
{
    for (int i = n - 1; i > 0; i--) {
        int j = (int)(sl_test_rand(state) % (uint64_t)(i + 1));
        int t = a[i];
        a[i] = a[j];
        a[j] = t;
    }
}

double sl_test_median(double *v, size_t n)
{
    if (n == 0)
        return NAN;
    qsort(v, n, sizeof *v, sl_cmp_double);
    return v[n / 2];
}

bool sl_test_same_meta(const char *name, const sl_meta *a, const sl_meta *b)
{
    bool same = strcmp(a->format, b->format) == 0 && a->bits_per_sample == b->bits_per_sample &&
                a->is_float == b->is_float && strcmp(a->colorspace, b->colorspace) == 0 &&
                a->exposure_time == b->exposure_time && a->f_number == b->f_number &&
                a->iso == b->iso && a->focal_length_mm == b->focal_length_mm &&
                strcmp(a->make, b->make) == 0 && strcmp(a->model, b->model) == 0 &&
                strcmp(a->lens, b->lens) == 0 && strcmp(a->datetime, b->datetime) == 0 &&
                a->orientation == b->orientation && a->attr_count == b->attr_count &&
                a->has_chromaticities == b->has_chromaticities && a->envmap == b->envmap;
    for (int i = 0; same && i < a->attr_count; i++)
        same = strcmp(a->attrs[i].name, b->attrs[i].name) == 0 &&
               strcmp(a->attrs[i].value, b->attrs[i].value) == 0;
    if (!same)
        printf("  %s: native %s %d-bit '%s' t=%.9g N=%.9g iso=%g f=%.9g '%s' '%s' '%s' '%s' o=%d "
               "%d attrs\n  %s: OIIO   %s %d-bit '%s' t=%.9g N=%.9g iso=%g f=%.9g '%s' '%s' '%s' "
               "'%s' o=%d %d attrs\n",
               name, a->format, a->bits_per_sample, a->colorspace, a->exposure_time, a->f_number,
               a->iso, a->focal_length_mm, a->make, a->model, a->lens, a->datetime,
               a->orientation, a->attr_count, name, b->format, b->bits_per_sample, b->colorspace,
               b->exposure_time, b->f_number, b->iso, b->focal_length_mm, b->make, b->model,
               b->lens, b->datetime, b->orientation, b->attr_count);
    return same;
}

int sl_test_finish(void)
{
    printf("%d passed, %d failed, %d skipped\n", sl_test_passed, sl_test_failed, sl_test_skipped);
    return sl_test_failed ? 1 : 0;
}

const char *sl_test_errmsg(const sl_error *err) { return err ? err->message : ""; }

double sl_test_chi2(const double *obs, const double *expct, int n, int *dof_out)
{
    double stat = 0.0, po = 0.0, pe = 0.0, last_o = 0.0, last_e = 0.0;
    int bins = 0;
    for (int i = 0; i < n; i++) {
        if (expct[i] == 0.0 && obs[i] > 0.0)
            return 0.0;
        po += obs[i];
        pe += expct[i];
        if (pe >= 5.0) {
            stat += (po - pe) * (po - pe) / pe;
            bins++;
            last_o = po;
            last_e = pe;
            po = pe = 0.0;
        }
    }
    if (pe > 0.0 && bins > 0) { /* a remainder under 5 joins the last pooled bin */
        stat -= (last_o - last_e) * (last_o - last_e) / last_e;
        last_o += po;
        last_e += pe;
        stat += (last_o - last_e) * (last_o - last_e) / last_e;
    }
    *dof_out = bins - 1;
    return sl_chi2_pvalue(stat, bins - 1);
}

int sl_test_fixture_write(const char *out, sl_image *img, sl_meta *meta, bool jpeg, sl_result r,
                          sl_error *err)
{
    if (!r && jpeg) {
        for (int y = 0; y < img->height; y++)
            for (int x = 0; x < img->width * img->channels; x++) {
                float *v = img->data + (size_t)y * img->stride + x;
                *v = sl_linear_to_srgb(*v > 1.0f ? 1.0f : *v);
            }
        r = sl_photo_write(out, img, meta, 8, err);
    } else if (!r) {
        sl_meta_set_rec709(meta);
        r = sl_exr_write(out, img, meta, SL_PIXEL_FLOAT, err);
    }
    sl_image_free(img);
    sl_meta_free(meta);
    if (r) {
        fprintf(stderr, "make_fixture: %s\n", err->message);
        return 1;
    }
    return 0;
}
