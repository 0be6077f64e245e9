/* SPDX-License-Identifier: BSD-3-Clause */
#include "setlight/core.h"

#include <stdlib.h>
#include <string.h>

void sl_meta_init(sl_meta *meta) { memset(meta, 0, sizeof *meta); }

void sl_meta_free(sl_meta *meta)
{
    if (!meta)
        return;
    for (int i = 0; i < meta->attr_count; i++) {
        free(meta->attrs[i].name);
        free(meta->attrs[i].value);
    }
    free(meta->attrs);
    memset(meta, 0, sizeof *meta);
}

sl_result sl_meta_copy(const sl_meta *src, sl_meta *dst, sl_error *err)
{
    *dst = *src;
    dst->attrs = NULL;
    dst->attr_count = 0;
    for (int i = 0; i < src->attr_count; i++) {
        sl_result r = sl_meta_set(dst, src->attrs[i].name, src->attrs[i].value, err);
        if (r) {
            sl_meta_free(dst);
            return r;
        }
    }
    return SL_OK;
}

const char *sl_meta_get(const sl_meta *meta, const char *name)
{
    for (int i = 0; i < meta->attr_count; i++)
        if (strcmp(meta->attrs[i].name, name) == 0)
            return meta->attrs[i].value;
    return NULL;
}

sl_result sl_meta_set(sl_meta *meta, const char *name, const char *value, sl_error *err)
{
    char *v = strdup(value ? value : "");
    if (!v)
        return sl_error_set(err, SL_ERR_NOMEM, "out of memory for attribute %s", name);
    for (int i = 0; i < meta->attr_count; i++)
        if (strcmp(meta->attrs[i].name, name) == 0) {
            free(meta->attrs[i].value);
            meta->attrs[i].value = v;
            return SL_OK;
        }
    char *n = strdup(name);
    sl_attr *grown = realloc(meta->attrs, (size_t)(meta->attr_count + 1) * sizeof *grown);
    if (!n || !grown) {
        free(v);
        free(n);
        if (grown)
            meta->attrs = grown;
        return sl_error_set(err, SL_ERR_NOMEM, "out of memory for attribute %s", name);
    }
    meta->attrs = grown;
    meta->attrs[meta->attr_count].name = n;
    meta->attrs[meta->attr_count].value = v;
    meta->attr_count++;
    return SL_OK;
}

void sl_meta_set_rec709(sl_meta *meta)
{
    static const float rec709[8] = {0.64f, 0.33f, 0.30f, 0.60f, 0.15f, 0.06f, 0.3127f, 0.3290f};
    memcpy(meta->chromaticities, rec709, sizeof rec709);
    meta->has_chromaticities = true;
}
