/* SPDX-License-Identifier: BSD-3-Clause */
/* The image format (RAW, JPEG, RAW+JPEG): what a camera's choice labels
 * mean, which one to pick, and setting it with a read-back, the same for
 * every backend. Labels differ by vendor (libgphoto2's ptp2 driver: Nikon
 * "NEF (Raw)", "NEF+Fine", "JPEG Fine"; Canon "RAW", "cRAW", "Large Fine
 * JPEG", "RAW + Large Fine JPEG"; Sony "RAW", "RAW+JPEG", "Fine"). */
#include <ctype.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

#include "camera_backend.h"

static const char *const k_names[] = {"keep", "jpeg", "raw", "raw+jpeg"};

const char *sl_image_format_name(sl_image_format format)
{
    return format >= SL_FORMAT_KEEP && format <= SL_FORMAT_RAW_JPEG ? k_names[format] : "?";
}

sl_result sl_image_format_parse(const char *text, sl_image_format *format, sl_error *err)
{
    for (int f = SL_FORMAT_KEEP; f <= SL_FORMAT_RAW_JPEG; f++)
        if (!strcasecmp(text, k_names[f])) {
            *format = (sl_image_format)f;
            return SL_OK;
        }
    return sl_error_set(err, SL_ERR_USAGE, "'%s': not an image format (raw, jpeg, raw+jpeg, keep)",
                        text);
}

static const char *const k_raw_ext[] = {"cr2", "cr3", "nef", "nrw", "arw", "dng",
                                        "raf", "orf", "rw2", "pef", "srw", "iiq"};
#define COUNT(a) ((int)(sizeof(a) / sizeof(a)[0]))

sl_image_format sl_image_format_of_file(const char *name)
{
    const char *dot = strrchr(name, '.');
    if (!dot)
        return SL_FORMAT_KEEP;
    for (int i = 0; i < COUNT(k_raw_ext); i++)
        if (!strcasecmp(dot + 1, k_raw_ext[i]))
            return SL_FORMAT_RAW;
    return !strcasecmp(dot + 1, "jpg") || !strcasecmp(dot + 1, "jpeg") ? SL_FORMAT_JPEG
                                                                       : SL_FORMAT_KEEP;
}

/* Whole words only: "Fine" is not in "Finest", "RAW" not in "Drawing". */
static bool has_word(const char *text, const char *word)
{
    size_t n = strlen(word);
    for (const char *p = text; (p = strstr(p, word)); p++) {
        bool start = p == text || !isalnum((unsigned char)p[-1]);
        bool end = !isalnum((unsigned char)p[n]);
        if (start && end)
            return true;
    }
    return false;
}

sl_image_format sl_image_format_of_label(const char *label, int *rank)
{
    char l[128];
    size_t n = 0;
    for (; label && label[n] && n < sizeof l - 1; n++)
        l[n] = (char)tolower((unsigned char)label[n]);
    l[n] = 0;
    if (rank)
        *rank = 0;
    if (strstr(l, "unknown") || strstr(l, "heif") || strstr(l, "heic") || strstr(l, "tif"))
        return SL_FORMAT_KEEP;
    /* reduced raws: mRAW, sRAW (fewer pixels), cRAW (lossy) */
    bool small_raw = strstr(l, "mraw") || strstr(l, "sraw") || strstr(l, "m-raw") ||
                     strstr(l, "s-raw") || strstr(l, "raw (s") || strstr(l, "raw (m");
    bool lossy_raw = has_word(l, "craw");
    bool raw = has_word(l, "raw") || has_word(l, "nef") || small_raw || lossy_raw ||
               has_word(l, "rw2") || has_word(l, "arw") || has_word(l, "orf") ||
               has_word(l, "dng") || has_word(l, "raf") || has_word(l, "pef");
    int quality = strstr(l, "extra fine") || strstr(l, "x.fine") || strstr(l, "superfine") ? 4
                  : has_word(l, "fine")                                                    ? 3
                  : has_word(l, "normal") || has_word(l, "standard") || has_word(l, "std") ? 2
                  : has_word(l, "basic") || has_word(l, "light") || has_word(l, "economy") ? 1
                                                                                           : 0;
    bool jpeg = has_word(l, "jpeg") || has_word(l, "jpg") || quality > 0;
    if (jpeg && quality == 0)
        quality = 2;
    int size = has_word(l, "small") || has_word(l, "s1") || has_word(l, "s2") || has_word(l, "s3")
                   ? 0
               : has_word(l, "medium") || has_word(l, "m1") || has_word(l, "m2") ? 1
                                                                                 : 2;
    int raw_rank = !raw ? 0 : small_raw ? 0 : lossy_raw ? 1 : 2;
    if (rank)
        *rank = raw_rank * 100 + quality * 10 + size * 2 - (strchr(l, '*') != NULL);
    return raw && jpeg ? SL_FORMAT_RAW_JPEG
           : raw       ? SL_FORMAT_RAW
           : jpeg      ? SL_FORMAT_JPEG
                       : SL_FORMAT_KEEP;
}

#define MAX_CHOICES 64

typedef struct choices {
    char labels[MAX_CHOICES][64];
    int count;
    char current[64];
} choices;

static sl_result read_choices(sl_camera *c, choices *ch, sl_error *err)
{
    memset(ch, 0, sizeof *ch);
    if (!c->ops->format_choices)
        return sl_error_set(err, SL_ERR_CAMERA, "%s: the camera has no image format setting",
                            c->port);
    return c->ops->format_choices(c, ch->labels, MAX_CHOICES, &ch->count, ch->current, err);
}

/* The best label of the kind asked for, or -1. */
static int best_choice(const choices *ch, sl_image_format format)
{
    int best = -1, best_rank = -1;
    for (int i = 0; i < ch->count; i++) {
        int rank;
        if (sl_image_format_of_label(ch->labels[i], &rank) == format && rank > best_rank) {
            best = i;
            best_rank = rank;
        }
    }
    return best;
}

static sl_result choose(sl_camera *c, const choices *ch, sl_image_format format, int *index,
                        sl_error *err)
{
    if ((*index = best_choice(ch, format)) >= 0)
        return SL_OK;
    char list[512] = "";
    for (int i = 0; i < ch->count; i++) {
        size_t n = strlen(list);
        snprintf(list + n, sizeof list - n, "%s'%s'", i ? ", " : "", ch->labels[i]);
    }
    return sl_error_set(err, SL_ERR_USAGE,
                        "%s: the camera offers no %s image format (its choices: %s)", c->port,
                        sl_image_format_name(format), ch->count ? list : "none");
}

static void remember(sl_camera *c, sl_image_format format)
{
    c->files_per_shot = format == SL_FORMAT_RAW_JPEG ? 2 : 1;
}

/* The camera's choices and the index of the best for `format`; `label`
 * (may be NULL) gets it. */
static sl_result pick(sl_camera *c, sl_image_format format, choices *ch, int *index, char *label,
                      sl_error *err)
{
    if (label)
        label[0] = 0;
    sl_result r = read_choices(c, ch, err);
    if (!r)
        r = choose(c, ch, format, index, err);
    if (!r && label)
        snprintf(label, 64, "%s", ch->labels[*index]);
    return r;
}

sl_result sl_camera_format_choice(sl_camera *camera, sl_image_format format, char *label,
                                  sl_error *err)
{
    choices ch;
    int i;
    return pick(camera, format, &ch, &i, label, err);
}

sl_result sl_camera_set_format(sl_camera *camera, sl_image_format format, char *label,
                               sl_error *err)
{
    choices ch;
    int i;
    sl_result r = pick(camera, format, &ch, &i, label, err);
    if (r)
        return r;
    char want[64];
    snprintf(want, sizeof want, "%s", ch.labels[i]);
    /* written even when it already reads right: a body can read back a
     * format it does not shoot */
    if ((r = sl_camera_set_label(camera, want, err)) || (r = read_choices(camera, &ch, err)))
        return r;
    if (strcmp(ch.current, want) != 0)
        return sl_error_set(err, SL_ERR_CAMERA,
                            "%s: the camera ignored the image format change: it reads '%s' "
                            "after being set to '%s'",
                            camera->port, ch.current, want);
    remember(camera, format);
    return SL_OK;
}

sl_result sl_camera_get_format(sl_camera *camera, sl_image_format *format, char *label,
                               sl_error *err)
{
    *format = SL_FORMAT_KEEP;
    if (label)
        label[0] = 0;
    if (!camera->ops->format_choices) {
        remember(camera, SL_FORMAT_KEEP);
        return SL_OK;
    }
    choices ch;
    sl_result r = read_choices(camera, &ch, err);
    if (r)
        return r;
    *format = sl_image_format_of_label(ch.current, NULL);
    if (label)
        snprintf(label, 64, "%s", ch.current);
    remember(camera, *format);
    return SL_OK;
}
