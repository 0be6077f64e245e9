/* SPDX-License-Identifier: BSD-3-Clause */
/* The white furnace: every white lobe should return all the energy it
 * receives. Without compensation GGX loses what the single-scattering model
 * drops (about 60% at roughness 1, normal incidence); with it the loss is the
 * table's interpolation error. */
#include <jansson.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/render.h"

static const double furnace_cos[] = {0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.7, 0.85, 1.0};
#define N_COS ((int)(sizeof furnace_cos / sizeof furnace_cos[0]))
#define N_ROUGH 11 /* 0, 0.1, ..., 1 */

typedef struct family {
    const char *name;
    sl_material_type type;
    double anisotropy;
    bool rough; /* iterate over roughness */
} family;

static const family families[] = {
    {"lambert", SL_MAT_LAMBERT, 0.0, false},
    {"conductor", SL_MAT_CONDUCTOR, 0.0, true},
    {"conductor_aniso", SL_MAT_CONDUCTOR, 0.8, true},
    {"plastic", SL_MAT_PLASTIC, 0.0, true},
};
#define N_FAMILIES ((int)(sizeof families / sizeof families[0]))

static void material_for(const family *fam, double roughness, bool comp, sl_material *m)
{
    static const double white[3] = {1.0, 1.0, 1.0};
    switch (fam->type) {
    case SL_MAT_CONDUCTOR:
        sl_material_conductor(m, white, white, roughness);
        m->fresnel = SL_FRESNEL_ONE;
        break;
    case SL_MAT_PLASTIC:
        sl_material_plastic(m, white, 1.5, roughness);
        break;
    default:
        sl_material_lambert(m, 1.0, 1.0, 1.0);
        break;
    }
    m->anisotropy = fam->anisotropy;
    m->compensate = comp;
}

typedef struct job {
    sl_furnace_case *cases;
    sl_material *mats;
    int samples;
} job;

static void run_range(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    job *j = ctx;
    for (int64_t i = begin; i < end; i++) {
        double a[3];
        sl_bsdf_albedo(&j->mats[i], j->cases[i].cos_theta, j->samples, a);
        j->cases[i].albedo = (a[0] + a[1] + a[2]) / 3.0;
    }
}

sl_result sl_furnace_run(int samples, sl_furnace *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    if (samples < 16)
        return sl_error_set(err, SL_ERR_USAGE, "furnace: samples must be at least 16 (got %d)",
                            samples);
    int cap = N_FAMILIES * N_ROUGH * N_COS * 2;
    sl_furnace_case *cases = calloc((size_t)cap, sizeof *cases);
    sl_material *mats = calloc((size_t)cap, sizeof *mats);
    if (!cases || !mats) {
        free(cases);
        free(mats);
        return sl_error_set(err, SL_ERR_NOMEM, "furnace: out of memory");
    }
    int n = 0;
    for (int f = 0; f < N_FAMILIES; f++)
        for (int comp = 1; comp >= 0; comp--)
            for (int r = 0; r < (families[f].rough ? N_ROUGH : 1); r++)
                for (int c = 0; c < N_COS; c++) {
                    sl_furnace_case *k = &cases[n];
                    k->bsdf = families[f].name;
                    k->roughness = families[f].rough ? r / (double)(N_ROUGH - 1) : 0.0;
                    k->cos_theta = furnace_cos[c];
                    k->compensated = comp;
                    k->expected = 1.0;
                    material_for(&families[f], k->roughness, comp, &mats[n]);
                    n++;
                }
    job j = {cases, mats, samples};
    sl_parallel_for(n, 8, run_range, &j);
    free(mats);
    out->cases = cases;
    out->count = n;
    return SL_OK;
}

void sl_furnace_free(sl_furnace *f)
{
    free(f->cases);
    memset(f, 0, sizeof *f);
}

sl_result sl_furnace_json(const sl_furnace *f, char **json, sl_error *err)
{
    *json = NULL;
    json_t *root = json_object(), *arr = json_array();
    bool ok = root && arr && !json_object_set(root, "cases", arr);
    for (int i = 0; ok && i < f->count; i++) {
        const sl_furnace_case *k = &f->cases[i];
        json_t *o = json_pack("{s:s, s:f, s:f, s:b, s:f, s:f}", "bsdf", k->bsdf, "roughness",
                              k->roughness, "cos_theta", k->cos_theta, "compensated",
                              (int)k->compensated, "albedo", k->albedo, "expected", k->expected);
        ok = o && !json_array_append_new(arr, o);
    }
    if (ok)
        *json = json_dumps(root, JSON_INDENT(1) | JSON_REAL_PRECISION(8));
    json_decref(arr);
    json_decref(root);
    if (!*json)
        return sl_error_set(err, SL_ERR_NOMEM, "furnace: cannot build the JSON report");
    return SL_OK;
}
