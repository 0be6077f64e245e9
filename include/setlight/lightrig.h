/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * setlight lightrig: bright regions of a lat-long HDRI extracted into area
 * lights plus a residual dome, with an energy ledger, written as USD and JSON.
 *
 * Every light carries exactly the energy its region loses in the residual
 * dome (integral = sum over the region of (original - residual) x texel solid
 * angle, per channel, in double), so lights + dome = original by construction.
 * docs/lightrig.md has the method, the rig.json schema and the UsdLux mapping.
 */
#ifndef SETLIGHT_LIGHTRIG_H
#define SETLIGHT_LIGHTRIG_H

#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    SL_RIG_RECT = 0,
    SL_RIG_DISK,
    SL_RIG_SPHERE,
    SL_RIG_DISTANT /* unresolved (smaller than a few texels): the sun, far lamps */
} sl_rig_shape;

/* "rect", "disk", "sphere", "distant". */
const char *sl_rig_shape_name(sl_rig_shape s);

typedef enum { SL_RIG_METHOD_REGIONS = 0, SL_RIG_METHOD_MEDIANCUT } sl_rig_method;

#define SL_RIG_MAX_TAGS 32

typedef struct sl_rig_options {
    sl_rig_method method;
    /* A texel seeds a light when its luminance is above threshold x the
     * solid-angle-weighted median luminance of the map (default 8). */
    double threshold;
    /* ... and reaches this fraction of the brightest texel of its connected
     * bright area, so a lamp is not merged with the white wall it lights
     * (default 0.02; 0 keeps the whole area). */
    double peak_fraction;
    /* Keep the smallest set of lights carrying this share of the directional
     * energy (the energy of all candidates above their smooth fill) as a grey
     * sphere sees it and as a glossy one does; 0..1, default 0.9. */
    double energy;
    /* At most this many lights (>= 1); 0 means no limit (default). */
    int max_lights;
    /* Regions wider than this (sr) stay in the dome: a bright sky or a lit
     * wall is not a fixture, and the dome renders it exactly (default 0.3,
     * a cap of about 36 degrees; 0: no limit). */
    double max_solid_angle;
    /* Fragments closer than this (degrees, gap between their edges) are one
     * fixture (default 2). */
    double merge_degrees;
    /* Angular diameter given to unresolved sources, whose size the texels
     * cannot show (degrees, default 0.53: the sun). */
    double unresolved_degrees;
    /* Positions: distance > 0 puts every resolved light on a sphere of that
     * radius; room[] > 0 on a box room[0] wide (X), room[1] deep (Z),
     * room[2] high (Y), centred on the capture point horizontally, floor at
     * -capture_height. Both 0: at infinity. */
    double distance;
    double room[3];
    double capture_height;
    /* Artist tags, as on set: (latitude, longitude) in degrees. The region
     * at (or within 2 degrees of) an include is always kept, and is grown
     * from the brightest texel there when nothing was detected; the region
     * at an exclude stays in the dome. */
    double include[SL_RIG_MAX_TAGS][2];
    int include_count;
    double exclude[SL_RIG_MAX_TAGS][2];
    int exclude_count;
} sl_rig_options;

void sl_rig_options_default(sl_rig_options *opt);

typedef struct sl_rig_light {
    sl_rig_shape shape;
    double direction[3];   /* unit, from the capture point (lat-long convention) */
    double solid_angle;    /* sr */
    double integral[3];    /* sum (original - residual) dw over the region */
    double radiance[3];    /* integral / solid_angle */
    double axis_u[3];      /* tangent frame: major axis (rect width), unit */
    double axis_v[3];      /* minor axis, direction x axis_u ... see docs */
    double angular_size[2];/* full angular width and height (rad); disk: both the diameter */
    double share;          /* of the grey sphere's light: luminous power */
    double share_glossy;   /* of the glossy sphere's highlights (see docs) */
    bool has_position;
    double position[3];    /* metres from the capture point */
    double size[2];        /* physical width, height (disk/sphere: diameter twice) */
    int texels;            /* texels in its region */
    char texture[256];     /* texture file name (beside the USD), "" if none */
    /* Set by sl_rig_write_textures_mode: the solid-angle-weighted coefficient
     * of variation of the region's luminance above the dome over its fully
     * covered texels (3 texels inside its edge; 0 when fewer than
     * SL_RIG_TEXTURE_MIN_TEXELS), and why the light is or is not textured. */
    double variation;
    char texture_reason[192];
} sl_rig_light;

typedef struct sl_rig_skip {
    double direction[3];
    double solid_angle;
    double integral[3];
    double share;
    double share_glossy;
    char reason[160];
} sl_rig_skip;

typedef struct sl_rig {
    int width, height;
    sl_rig_light *lights;
    int light_count;
    sl_rig_skip *skipped;
    int skipped_count;
    sl_image residual;     /* RGB, same size as the map: the dome */
    int *labels;           /* width x height: light index + 1, 0 = dome */
    double original[3];    /* integral of the map (after removing NaN/Inf) */
    double lights_sum[3];
    double dome[3];
    double relative_error; /* max over channels |lights + dome - original| / original */
    int64_t nonfinite;     /* NaN/Inf samples set to 0 before extraction */
    int64_t negative;      /* negative samples (lossy codecs) set to 0 */
    double median_luminance;
    double threshold_luminance;
} sl_rig;

/* Extracts a rig from an RGB(A) lat-long (2:1; alpha ignored). NaN/Inf
 * samples are counted in rig->nonfinite, negative ones in rig->negative,
 * and both treated as 0 (the ledger's original is the map after that). A black map gives
 * an empty rig. SL_ERR_USAGE for bad options (max_lights < 0, energy outside
 * (0, 1], a room that does not contain the capture point). */
sl_result sl_rig_extract(const sl_image *env, const sl_rig_options *opt, sl_rig *rig,
                         sl_error *err);
void sl_rig_free(sl_rig *rig);

/* The rig as USD ASCII (UsdLux), written atomically. dome_file is the path
 * written into the DomeLight's texture (relative to the .usda or absolute). */
sl_result sl_rig_write_usda(const sl_rig *rig, const char *path, const char *dome_file,
                            sl_error *err);
/* The rig as rig.json (version 2), written atomically; dome_file as above (may be NULL). */
sl_result sl_rig_write_json(const sl_rig *rig, const char *path, const char *dome_file,
                            sl_error *err);
/* The rig's JSON text (caller frees with free()). */
char *sl_rig_json_string(const sl_rig *rig, const char *dome_file);
/* Textured area lights: for every rect light (positioned or at infinity), the region's
 * light above the dome as seen from the capture point (column 0 at the
 * light's local +X, row 0 at +Y), each channel normalised to a
 * solid-angle-weighted mean of 1 (the light's colour is the mean radiance) so
 * power and colour are unchanged, written as PREFIX_light_NN.exr
 * (float); the base name goes into light->texture. env is the map the rig
 * was extracted from. */
sl_result sl_rig_write_textures(sl_rig *rig, const sl_image *env, const char *prefix,
                                sl_error *err);
/* Which lights get a texture: AUTO the rect lights whose variation (see
 * sl_rig_light) is at least SL_RIG_TEXTURE_VARIATION (a graded window, not a
 * uniform fixture: docs/lightrig.md has the measurements behind the
 * threshold), ALL every rect light, NONE none. UsdLux textures rect lights
 * only: a graded disk or sphere stays uniform and its reason says so. */
typedef enum {
    SL_RIG_TEXTURES_AUTO = 0,
    SL_RIG_TEXTURES_ALL,
    SL_RIG_TEXTURES_NONE
} sl_rig_texture_mode;
#define SL_RIG_TEXTURE_VARIATION 0.25
#define SL_RIG_TEXTURE_MIN_TEXELS 16
/* sl_rig_write_textures for the lights mode chooses; fills every light's
 * variation and texture_reason (also the untextured ones). */
sl_result sl_rig_write_textures_mode(sl_rig *rig, const sl_image *env, const char *prefix,
                                     sl_rig_texture_mode mode, sl_error *err);
/* A PNG of the map with every light outlined and numbered (1-based, as in
 * the USD and JSON order). */
sl_result sl_rig_write_preview(const sl_rig *rig, const sl_image *env, const char *path,
                               sl_error *err);

/* ---- Validation: the rig against the map it came from ---- */

#define SL_RIG_VALIDATE_SCENES 3

typedef struct sl_rig_validation {
    int width;
    int64_t spp;      /* samples per pixel done (requested, rounded up to a multiple of 4) */
    int64_t spp_done; /* the last scene's, while rendering */
    const char *scene[SL_RIG_VALIDATE_SCENES]; /* "grey", "chrome", "shadow" */
    double error[SL_RIG_VALIDATE_SCENES];      /* relative RMSE, rig against map */
    double seconds_map[SL_RIG_VALIDATE_SCENES], seconds_rig[SL_RIG_VALIDATE_SCENES];
    /* The Monte Carlo noise of the rig-minus-map difference (relative to
     * the map render, from two half renders with different seeds) and the
     * error left when it is taken out: sqrt(max(0, error^2 - noise^2)). */
    double noise[SL_RIG_VALIDATE_SCENES];
    double beyond_noise[SL_RIG_VALIDATE_SCENES];
    double seconds, cpu_seconds; /* wall and process CPU time of the whole validation */
    /* The renders as compared: RGBA, RGB multiplied by the map render's
     * alpha (the objects only). Freed by sl_rig_validation_free. */
    sl_image map[SL_RIG_VALIDATE_SCENES], rig[SL_RIG_VALIDATE_SCENES];
} sl_rig_validation;

/* Renders the grey, chrome and shadow presets (width pixels wide, spp
 * samples, direct light and one bounce) under the map and under the rig
 * file (rig.json, read back as the renderer reads it) with the same seeds,
 * and compares them on the objects (camera rays that miss see black).
 * Free *out with sl_rig_validation_free, also after failure. */
sl_result sl_rig_validate(const sl_image *env, const char *rig_json, int width, int64_t spp,
                          sl_rig_validation *out, sl_error *err);
void sl_rig_validation_free(sl_rig_validation *v);

/* Adds the validation to a report: a table (relative RMSE, spp, size,
 * render times) and for each scene the render under the map, under the rig
 * and a false-colour difference, as PNGs named PREFIX<scene>_map.png,
 * PREFIX<scene>_rig.png, PREFIX<scene>_diff.png, plus PREFIXdiff_scale.png
 * (the colour bar). PREFIX may name a subfolder of the report's folder
 * ("RIG.validate/"), which must exist. */
sl_result sl_rig_validate_report(sl_report *rep, const sl_rig_validation *v, const char *prefix,
                                 sl_error *err);

/* Checks that DIR/NAME.html and DIR/NAME can be replaced: each absent, or
 * a file and a folder respectively. */
sl_result sl_rig_validate_report_check(const char *dir, const char *name, sl_error *err);

/* ---- The rig stage, files to files ---- */

typedef struct sl_rig_run_options {
    const char *input_path;       /* the lat-long (read as sl_latlong_read) */
    const char *input_colorspace; /* NULL: the file's own, else the default (sRGB for 8/16-bit) */
    const char *out_path;         /* RIG.usda */
    const char *json_path;        /* the rig as JSON too, or NULL */
    const char *residual_path;    /* NULL: RIG_residual.exr beside RIG.usda */
    const char *preview_path;     /* PNG with the lights outlined, or NULL */
    sl_rig_options rig;           /* sl_rig_options_default */
    sl_rig_texture_mode textures; /* AUTO */
    /* > 0: the validation renders (grey, chrome, shadow; validate_width px,
     * default 96) under map and rig, and the report RIG.validate.html with
     * its files in RIG.validate/ beside RIG.usda. 0: none (default). */
    int64_t validate_spp;
    int validate_width;
} sl_rig_run_options;

void sl_rig_run_options_init(sl_rig_run_options *o);

typedef struct sl_rig_run_result {
    sl_rig rig;                   /* lights, skipped candidates, residual, ledger */
    bool black;                   /* the map was black: an empty rig */
    double seconds;               /* the whole run */
    bool validated;
    sl_rig_validation validation; /* when validated */
    char residual_path[4096];     /* as written */
    char report_path[4096];       /* RIG.validate.html when validated */
    char *json;                   /* every number above: what `rig --json` prints (owned) */
} sl_rig_run_result;

/* Reads the map, extracts the rig, writes the residual dome (with its
 * provenance), the light textures, the USD, the JSON and preview when asked
 * and the validation report, all as one output set: on failure every
 * earlier output stays. Messages name the input file. Free *res with
 * sl_rig_run_result_free, also after failure. */
sl_result sl_rig_run(const sl_rig_run_options *o, sl_rig_run_result *res, sl_error *err);
void sl_rig_run_result_free(sl_rig_run_result *res);

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_LIGHTRIG_H */
