/* SPDX-License-Identifier: BSD-3-Clause */
/* A growing string for pages, scripts and messages built piece by piece. */
#include "setlight/core.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Room for n more characters and the NUL. */
static bool reserve(sl_text *t, size_t n)
{
    if (t->failed)
        return false;
    if (t->len + n + 1 <= t->cap)
        return true;
    size_t cap = t->cap ? t->cap : 256;
    while (cap < t->len + n + 1)
        cap *= 2;
    char *grown = realloc(t->s, cap);
    if (!grown) {
        t->failed = true;
        return false;
    }
    t->s = grown;
    t->cap = cap;
    return true;
}

bool sl_text_add(sl_text *t, const char *s, size_t n)
{
    if (!reserve(t, n))
        return false;
    memcpy(t->s + t->len, s, n);
    t->len += n;
    t->s[t->len] = '\0';
    return true;
}

bool sl_text_add_str(sl_text *t, const char *s) { return sl_text_add(t, s, strlen(s)); }

bool sl_text_printf(sl_text *t, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (n < 0) {
        t->failed = true;
        return false;
    }
    if (!reserve(t, (size_t)n))
        return false;
    va_start(ap, fmt);
    vsnprintf(t->s + t->len, (size_t)n + 1, fmt, ap);
    va_end(ap);
    t->len += (size_t)n;
    return true;
}

void sl_text_free(sl_text *t)
{
    free(t->s);
    *t = (sl_text){0};
}
