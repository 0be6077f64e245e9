/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * setlight render: the validation renderer. BSDFs, light and environment
 * sampling, MIS, integrators, validation scenes and convergence reports.
 * See docs/render.md.
 */
#ifndef SETLIGHT_RENDER_H
#define SETLIGHT_RENDER_H

#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ================================================================== */
/* BSDFs and materials                                                 */
/* ================================================================== */

/* Shading happens in a local frame: +Z is the surface normal; wo and wi
 * point away from the surface; both unit length. Values are double.
 * Models and references: docs/render-bsdf.md. */
typedef enum {
    SL_MAT_LAMBERT = 0, /* diffuse, albedo base_color */
    SL_MAT_CONDUCTOR,   /* GGX metal; Fresnel from base_color (reflectance at normal
                           incidence) and edge_tint (Gulbrandsen 2014); roughness 0 = delta mirror */
    SL_MAT_PLASTIC,     /* Lambert base_color under a GGX dielectric coat of index ior */
    SL_MAT_COUNT
} sl_material_type;

typedef enum {
    SL_FRESNEL_SCHLICK = 0, /* F0 = base_color */
    SL_FRESNEL_ARTIST,      /* Gulbrandsen: base_color + edge_tint -> complex IOR */
    SL_FRESNEL_DIELECTRIC,  /* exact, from ior */
    SL_FRESNEL_ONE          /* F = 1: the white furnace conductor */
} sl_fresnel_mode;

typedef struct sl_material {
    sl_material_type type;
    sl_fresnel_mode fresnel;
    double base_color[3];
    double edge_tint[3];
    double roughness;  /* perceptual, 0..1; GGX alpha = roughness^2 */
    double anisotropy; /* 0..1 (0 = isotropic); alpha_x, alpha_y per Kulla-Conty/Burley */
    double ior;        /* dielectric coat (plastic) */
    bool compensate;   /* Kulla-Conty multiple-scattering energy compensation */
} sl_material;

/* Result of sl_bsdf_sample (a C name cannot be both a type and a function). */
typedef struct sl_bsdf_sample_rec {
    double wi[3]; /* sampled direction, local frame */
    double f[3];  /* BSDF value; for a delta lobe: F / |cos wi| so f*cos/pdf = weight */
    double pdf;   /* solid-angle pdf; for a delta lobe the probability of choosing it */
    bool delta;
} sl_bsdf_sample_rec;

/* Presets: grey 18% Lambert, chrome (measured reflectance documented in
 * docs/render-bsdf.md), generic conductor and plastic. All compensate. */
void sl_material_lambert(sl_material *m, double r, double g, double b);
void sl_material_chrome(sl_material *m);
void sl_material_conductor(sl_material *m, const double reflectance[3], const double edge_tint[3],
                           double roughness);
void sl_material_plastic(sl_material *m, const double albedo[3], double ior, double roughness);
/* Validates parameters: NaN/negative/out-of-range -> SL_ERR_INPUT naming the field. */
sl_result sl_material_check(const sl_material *m, sl_error *err);

/* Non-delta part of the BSDF (f, not multiplied by cos). */
void sl_bsdf_eval(const sl_material *m, const double wo[3], const double wi[3], double f[3]);
/* Solid-angle pdf of sl_bsdf_sample for the non-delta part. */
double sl_bsdf_pdf(const sl_material *m, const double wo[3], const double wi[3]);
/* Samples wi given three uniform numbers; false when no direction (e.g. below the surface). */
bool sl_bsdf_sample(const sl_material *m, const double wo[3], const double u[3],
                    sl_bsdf_sample_rec *s);
/* True when the material has only a delta lobe (mirror). Lets the integrator skip light sampling. */
bool sl_bsdf_is_delta(const sl_material *m);
/* Directional albedo: integral of f cos over the hemisphere for wo at cos_theta,
 * estimated with n stratified samples (for the furnace and tests). */
void sl_bsdf_albedo(const sl_material *m, double cos_theta, int n, double albedo[3]);

/* White furnace: the directional albedo of white (energy-preserving) lobes
 * over roughness 0..1 and incidence, with and without compensation. */
typedef struct sl_furnace_case {
    const char *bsdf;  /* "lambert", "conductor", "conductor_aniso", "plastic" (static) */
    double roughness;
    double cos_theta;
    bool compensated;
    double albedo;     /* mean over channels (the lobes are white) */
    double expected;   /* 1: a white energy-preserving lobe keeps all energy */
} sl_furnace_case;

typedef struct sl_furnace {
    sl_furnace_case *cases;
    int count;
} sl_furnace;

/* Runs every case with `samples` stratified samples each (>= 16); deterministic
 * and parallel over cases. */
sl_result sl_furnace_run(int samples, sl_furnace *out, sl_error *err);
void sl_furnace_free(sl_furnace *f);
/* {"cases": [{"bsdf", "roughness", "cos_theta", "compensated", "albedo",
 * "expected"}, ...]}; *json is malloc'ed, free() it. */
sl_result sl_furnace_json(const sl_furnace *f, char **json, sl_error *err);

/* ================================================================== */
/* Scenes, lights, cameras, integrator                                 */
/* ================================================================== */

/* World space is right-handed, +Y up, the same frame as core's lat-long:
 * a dome direction d looks up the dome image at sl_dir_to_latlong(rot^T d).
 * Units are arbitrary (the validation spheres have radius 1). */

typedef enum { SL_SHAPE_SPHERE = 0, SL_SHAPE_RECT, SL_SHAPE_DISK } sl_shape_type;

typedef struct sl_shape {
    sl_shape_type type;
    double center[3];
    double radius;    /* sphere, disk */
    double u[3], v[3]; /* rect: half-edge vectors (orthogonal); normal = u x v */
    double normal[3]; /* rect, disk: unit normal; both faces shade alike */
    int material;     /* index into sl_scene.materials */
} sl_shape;

typedef enum {
    SL_CAMERA_ORTHOGRAPHIC = 0,
    SL_CAMERA_PERSPECTIVE,
    SL_CAMERA_FISHEYE /* equisolid angle, r = 2 f sin(theta / 2), circular image */
} sl_camera_type;

typedef struct sl_camera {
    sl_camera_type type;
    double position[3];
    double forward[3]; /* unit view direction */
    double up[3];      /* unit, orthogonal to forward */
    double ortho_width; /* orthographic: world width seen across the image */
    double fov_deg;     /* perspective: horizontal field of view; fisheye: diameter of the image circle, which spans the image width */
    int width, height;  /* pixels */
} sl_camera;

/* The validation camera (docs/render.md): orthographic, looking along +Z
 * from z = -10 toward the origin, +Y up, image right = -X, the unit sphere
 * exactly filling the image width; then orbited about the origin by azimuth
 * (about +Y, the view turning toward +X) and elevation (the camera rising,
 * looking down; 90 looks straight down with +Z at the image top). */
void sl_camera_validation(sl_camera *cam, int width, int height, double ortho_width,
                          double azimuth_deg, double elevation_deg);

/* An environment light: a lat-long image times intensity, turned by rot
 * (world_dir = rot * map_dir), importance-sampled in double precision. */
typedef struct sl_dome_sampler sl_dome_sampler; /* private */

typedef struct sl_dome {
    bool present;
    sl_image image;       /* RGB, sanitised: no NaN/Inf/negative texels */
    double rot[3][3];
    double intensity;
    int64_t bad_texels;   /* NaN/Inf/negative samples replaced by 0 at load */
    sl_dome_sampler *sampler;
} sl_dome;

/* Area and distant lights with UsdLux's meaning: each light emits along its
 * local -Z axis (rect, disk: from the face whose normal is -Z; sphere: all
 * around). Radiance = color * intensity * 2^exposure; with normalize, divided
 * by the emitting area (rect, disk, sphere) or, for a distant light, chosen so
 * that the illuminance at normal incidence is intensity * 2^exposure. */
typedef enum { SL_LIGHT_RECT = 0, SL_LIGHT_DISK, SL_LIGHT_SPHERE, SL_LIGHT_DISTANT } sl_light_type;

typedef struct sl_light {
    sl_light_type type;
    double position[3];
    double axis_x[3], axis_y[3], axis_z[3]; /* orthonormal, right-handed */
    double width, height; /* rect, along axis_x and axis_y */
    double radius;        /* disk, sphere */
    double angle_deg;     /* distant: angular diameter (0 = a delta light) */
    double color[3];
    double intensity, exposure;
    bool normalize;
    sl_image texture;     /* rect only, optional (RGB multiplies color; row 0 at +axis_y) */
    double radiance[3];   /* derived by sl_scene_add_light */
    sl_distrib2d texture_dist; /* derived: a textured rect is sampled by its texture */
} sl_light;

typedef struct sl_scene {
    sl_light *lights;
    int light_count;
    sl_shape *shapes;
    int shape_count;
    sl_material *materials;
    int material_count;
    sl_camera camera;
    sl_dome dome;
    bool background_env; /* camera rays that miss see the dome (else black, alpha 0) */
    char name[64];
} sl_scene;

void sl_scene_init(sl_scene *scene);
void sl_scene_free(sl_scene *scene);
/* Checks the material (sl_material_check) and appends it; *index gets its slot. */
sl_result sl_scene_add_material(sl_scene *scene, const sl_material *m, int *index, sl_error *err);
sl_result sl_scene_add_sphere(sl_scene *scene, const double center[3], double radius, int material,
                              sl_error *err);
/* Rect centred at `center` with half-edge vectors u, v (made orthogonal). */
sl_result sl_scene_add_rect(sl_scene *scene, const double center[3], const double u[3],
                            const double v[3], int material, sl_error *err);
sl_result sl_scene_add_disk(sl_scene *scene, const double center[3], const double normal[3],
                            double radius, int material, sl_error *err);
/* Copies env (a lat-long, RGB or RGBA; extra channels ignored), counts and
 * zeroes NaN/Inf/negative texels, builds the sampling distribution.
 * rotation_deg turns the dome about +Y. `source` names it in messages. */
sl_result sl_scene_set_dome(sl_scene *scene, const sl_image *env, double rotation_deg,
                            double intensity, const char *source, sl_error *err);

/* Validates and appends a light (the scene takes over light->texture, also
 * on failure). The axes are re-orthonormalised from axis_z and axis_y. */
sl_result sl_scene_add_light(sl_scene *scene, sl_light *light, sl_error *err);
/* Reads a rig.json version 1 (docs/lightrig.md; mapping in docs/render.md):
 * each light keeps its direction, solid angle and radiance as seen from the
 * origin, plus the residual dome. Textures and the dome file are resolved
 * relative to the rig's folder. */
sl_result sl_scene_read_rig(sl_scene *scene, const char *path, sl_error *err);
/* The most lights a rig or scene file may hold, and objects and materials a
 * scene file may hold (a real rig has tens of lights): more is SL_ERR_INPUT
 * before any is built. Files over SL_MAX_JSON_BYTES are refused unread. */
#define SL_RENDER_MAX_LIGHTS 4096
#define SL_RENDER_MAX_OBJECTS 4096

/* Validation scenes: "grey", "chrome", "chart", "refs", "shadow", "materials".
 * Sets shapes, materials and camera (width pixels wide); the dome is left
 * to the caller. SL_ERR_USAGE for an unknown name. */
sl_result sl_scene_preset(sl_scene *scene, const char *name, int width, sl_error *err);
/* Space-separated preset names, static. */
const char *sl_scene_preset_names(void);

/* The ColorChecker Classic reference: 24 linear Rec.709 albedos in chart
 * order (dark skin ... black), from X-Rite's post-November-2014 sRGB values. */
extern const double SL_COLORCHECKER_LINEAR[24][3];
extern const char *const SL_COLORCHECKER_NAMES[24];

/* Reads a scene file (docs/render.md): camera, materials, objects. Values
 * that are NaN, negative where they must not be, or of the wrong type are
 * SL_ERR_INPUT naming the field and the file. */
sl_result sl_scene_read_json(sl_scene *scene, const char *path, int width, sl_error *err);

/* What the commands do to set up a scene: scene_arg names a preset or, when
 * it is an existing path or ends in .json, a scene file; then the lighting
 * from exactly one of env (a lat-long image read by sl_latlong_read: from
 * env_colorspace, or the file's colour space when NULL; turned and scaled)
 * and rig. */
sl_result sl_scene_load(sl_scene *scene, const char *scene_arg, int width, const char *env,
                        const char *env_colorspace, double env_rotation_deg, double env_intensity,
                        const char *rig, sl_error *err);
/* True when sl_scene_load would read scene_arg as a file. */
bool sl_scene_arg_is_file(const char *scene_arg);

typedef enum {
    SL_STRATEGY_MIS = 0, /* BSDF + light sampling, power heuristic */
    SL_STRATEGY_UNIFORM, /* uniform hemisphere directions only */
    SL_STRATEGY_COSINE,  /* cosine-weighted directions only */
    SL_STRATEGY_BSDF,    /* BSDF sampling only */
    SL_STRATEGY_LIGHT,   /* light/dome sampling only (delta lobes still use the BSDF) */
    SL_STRATEGY_COUNT
} sl_strategy;

/* "mis", "uniform", "cosine", "bsdf", "light"; -1 if unknown. */
int sl_strategy_from_name(const char *name);
const char *sl_strategy_name(sl_strategy s);

struct sl_render_pass;

typedef struct sl_render_options {
    int64_t spp;            /* stop at this many samples per pixel (0 = no limit) */
    double time_limit;      /* seconds (0 = no limit) */
    double target_error;    /* estimated relative RMSE (0 = no limit) */
    int bounces;            /* diffuse/glossy bounces after the first hit (0 = direct only) */
    sl_strategy strategy;
    bool low_discrepancy;   /* Owen-scrambled Sobol (default) or independent random numbers */
    bool pixel_centers;     /* sample pixel centres only (no box filter), for tests */
    uint64_t seed;
    const sl_image *reference; /* optional: true error per pass */
    /* At a Lambert vertex, a light whose irradiance bound is below this
     * fraction of the brightest light's is not sampled there; BSDF sampling
     * still finds it (with full weight), so the image stays unbiased.
     * 0 samples every light. Default 1e-3. */
    double light_cull;
    /* Closed form (docs/render.md): pixels of an unoccluded Lambert object
     * under the dome alone get their exact value (no samples); where other
     * objects may shadow it, only the shadowed difference is sampled. Only
     * with the MIS strategy. Default on. */
    bool closed_form;
    /* Bound on the closed form's relative irradiance error per pixel (the
     * quadrature refines until its proven bound is below its share of it,
     * the interpolation of the map's rest is checked to its share);
     * 0 = default 1e-2, or half --target-error when that is smaller. */
    double closed_form_tolerance;
    /* Called after every pass (from the calling thread), e.g. for progress. */
    void (*on_pass)(void *ctx, const struct sl_render_pass *pass);
    void *on_pass_ctx;
    /* Tests: the plan's per-pixel pass stops at this image row, as if --time
     * ran out there before the rest's plan reached it (rows from it on are
     * sampled; their glossy pixels keep the coarse pass's closed form, run
     * first); 0 = no such cut. A deterministic stand-in for the deadline. */
    int plan_row_limit;
    /* Tests: the glossy coarse pass (run when the plan may be cut) stops
     * at this image row, as if the deadline came there: past its first
     * level of blocks, which always completes, its pixels from it on keep
     * what those blocks gave them, else their sun exact and sample the
     * rest of the map; 0 = no such cut. */
    int plan_coarse_row_limit;
    /* Tests: the glossy coarse pass stops after its image blocks of this
     * size (16, 8 or 4 px), as if the deadline came then: a pixel of a
     * block that failed its check keeps that block's interpolation, with
     * the difference the check found as its error estimate; 0 = no such
     * cut. */
    int plan_coarse_block_limit;
    /* Tests: the Lambert fill's refinement stops after this many
     * evaluations past its first pass, as if --time ran out there; 0 = no
     * such cut. */
    int64_t plan_eval_limit;
} sl_render_options;

void sl_render_options_init(sl_render_options *o); /* spp 64, MIS, low discrepancy */

typedef struct sl_render_pass {
    int64_t spp;            /* total samples per pixel after the pass */
    double seconds;         /* wall time since the start */
    double est_rel_rmse;    /* from the two half-buffers */
    double ref_rel_rmse;    /* against the reference, or -1 */
} sl_render_pass;

/* What the closed form computed: pixels exact, pixels whose shadowed part
 * was sampled (control variate), pixels sampled as before, and why none
 * when it could not apply. */
#define SL_CLOSED_FORM_MAX_OBJECTS 16
typedef struct sl_closed_form_stats {
    bool used;
    char reason[96];            /* why not used, or "" */
    int64_t exact_pixels, control_variate_pixels, sampled_pixels;
    int objects[SL_CLOSED_FORM_MAX_OBJECTS]; /* shapes with closed-form pixels */
    int object_count;
    double tolerance;           /* relative bound the quadrature refined to */
    double max_rel_bound;       /* largest proven relative bound of a pixel */
    double max_footprint_error; /* largest pixel-filter quadrature estimate, relative */
    int top_level, finest_level; /* mip levels of the lat-long cells (< 0: inside a texel) */
    int64_t evaluations, cells;  /* irradiance evaluations, cells visited */
    int lights_exact, lights_sampled; /* rig lights in the closed form; left to sampling
                                         (textured rects) */
    bool cut_by_time;            /* --time ran out while planning */
    int64_t cut_pixels;          /* pixels the plan would have made exact or control
                                    variates, sampled because of that cut (glossy rows;
                                    a Lambert pixel keeps its coarser value and bound) */
    int64_t sun_exact_pixels;    /* glossy pixels a cut left with their sun exact and the
                                    rest of the map sampled (at the render's spp) */
    int64_t at_tolerance_pixels; /* closed-form pixels refined to the tolerance (the
                                    others: a cut left their interpolation coarser) */
    int64_t coarse_pixels;       /* glossy pixels of rows a cut left that keep the coarse
                                    pass's rest and its error estimate */
    double coarse_tolerance;     /* that pass's tolerance (0 when no pixel kept it) */
    int64_t provisional_pixels;  /* of those, pixels whose coarse block failed its check and
                                    the cut came before a finer one: they keep its
                                    interpolation, the difference found as their estimate */
    int64_t refined_pixels;      /* of those, pixels the coarse pass interpolated, then evaluated
                                    (its refinement: the largest error estimates first) */
    double rms_rel_bound;        /* RMS over closed-form pixels of the relative bound */
    double seconds;
    /* Per object (as objects[]): its material's type, its exact and
     * control-variate pixels, those of them interpolated, its largest
     * relative bound. A Lambert object's bound is proven where none of its
     * pixels is interpolated; a rough glossy one's (glossy.c), or one with
     * interpolated pixels, is an error estimate. */
    sl_material_type object_material[SL_CLOSED_FORM_MAX_OBJECTS];
    int64_t object_exact[SL_CLOSED_FORM_MAX_OBJECTS], object_control[SL_CLOSED_FORM_MAX_OBJECTS];
    int64_t object_interpolated[SL_CLOSED_FORM_MAX_OBJECTS];
    double object_max_rel_bound[SL_CLOSED_FORM_MAX_OBJECTS];
    /* Exact or control-variate pixels whose value of the map's rest (a
     * glossy pixel's reflection, a Lambert pixel's irradiance) was
     * interpolated inside a checked block (the sun, and a Lambert pixel's
     * rig lights, are evaluated at every pixel); the sun: its texels and
     * their share of the map's luminous power (0 when no texel stands out). */
    int64_t interpolated_pixels;
    int64_t sun_texels;
    double sun_share;
    /* Lambert pixels other objects shadow whose shadowed part was computed
     * (no bounces, no rig light), so exact instead of
     * control variates; that quadrature's evaluations and cells. */
    int64_t shadow_exact_pixels, shadow_evaluations, shadow_cells;
} sl_closed_form_stats;

/* What the closed form computed, in words, for logs and reports: the dome's
 * lat-long cells (e.g. "dome cells of 64x64 texels, split down to 1/2 texel
 * where the horizon cuts them"), the rig lights exact and sampled, and
 * whether --time cut the plan short. Returns buf. */
const char *sl_closed_form_describe(const sl_closed_form_stats *st, char *buf, size_t size);

typedef struct sl_render_stats {
    sl_render_pass *passes;
    int pass_count;
    int64_t spp;
    double seconds;
    double cpu_seconds;          /* process CPU time spent in the render */
    double samples_per_second;   /* camera samples taken per wall second */
    int64_t samples;             /* camera samples taken: pixels x spp, less what
                                    adaptive sampling (--target-error) saved */
    int64_t pixels_stopped_early; /* adaptive sampling: pixels that stopped before spp */
    int64_t camera_rays, shadow_rays, bsdf_rays;
    int64_t shadow_rays_skipped; /* nothing in the scene could occlude */
    int64_t zero_weight_skipped; /* light samples whose BSDF value or pdf was zero */
    int64_t lights_culled;       /* (vertex, light) pairs below the light_cull bound */
    int64_t lights_behind;       /* (vertex, light) pairs behind a one-sided light or below the horizon: exactly 0 */
    int64_t nonfinite_samples;   /* NaN/Inf sample values dropped (a bug if not 0) */
    int64_t dome_bad_texels;
    bool dome_sampled;           /* false when the dome is black (nothing to sample) */
    char stop_reason[32];        /* "spp", "time", "target-error", "exact" */
    sl_closed_form_stats closed_form;
} sl_render_stats;

void sl_render_stats_free(sl_render_stats *stats);
/* The stats as JSON (docs/render.md), written atomically. */
sl_result sl_render_stats_write_json(const sl_render_stats *stats, const sl_render_options *o,
                                     const char *path, sl_error *err);

/* Reads a reference image for sl_render_options.reference: RGB at the
 * scene camera's size (SL_ERR_INPUT naming the file otherwise). */
sl_result sl_render_read_reference(const char *path, const sl_scene *scene, sl_image *ref,
                                   sl_error *err);

/* ---- The render stage, files to files ---- */

typedef struct sl_render_run_options {
    const char *scene;            /* a preset name or a scene JSON file ("grey") */
    const char *env_path;         /* exactly one of env_path and rig_path lights it */
    const char *rig_path;
    const char *input_colorspace; /* the environment's (NULL: the file's own) */
    double rotate_deg, intensity; /* the environment's turn and scale (0, 1) */
    int width;                    /* image width (512) */
    bool view;                    /* turn a preset's validation camera to view_az, view_el */
    double view_az, view_el;
    bool background_env;          /* camera rays that miss see the environment */
    const sl_material *material;  /* every shape's material instead of the scene's, or NULL */
    const char *reference_path;   /* true error per pass against this image, or NULL */
    const char *stats_path;       /* per-pass statistics as JSON, or NULL */
    const char *out_path;         /* the render (float EXR) */
    sl_render_options render;     /* sl_render_options_init: spp, time, target error, ... */
} sl_render_run_options;

void sl_render_run_options_init(sl_render_run_options *o);

typedef struct sl_render_run_result {
    sl_render_stats stats;        /* spp, seconds, passes, rays, stop reason */
    int width, height;
    double est_rel_rmse;          /* the last pass's estimate */
    double ref_rel_rmse;          /* against the reference, -1 without */
    int64_t dome_bad_texels;      /* NaN, Inf or negative texels of the dome set to 0 */
    char *json;                   /* what `render --json` prints (owned) */
} sl_render_run_result;

/* Loads the scene and its light, renders, and writes the image (with
 * setlight:render and setlight:estimated_rel_rmse) and the statistics as
 * one output set. Free *res with sl_render_run_result_free, also after
 * failure. */
sl_result sl_render_run(const sl_render_run_options *o, sl_render_run_result *res,
                        sl_error *err);
void sl_render_run_result_free(sl_render_run_result *res);

/* Relative RMSE of img against ref over RGB: sqrt(sum (a-b)^2 / sum b^2).
 * SL_ERR_INPUT when the sizes differ. */
sl_result sl_relative_rmse(const sl_image *img, const sl_image *ref, double *out, sl_error *err);

/* ---- Convergence reports: error against time for each strategy ---- */

#define SL_CONVERGE_MAX 8

typedef struct sl_converge_curve {
    char name[32];             /* e.g. "mis+sobol" */
    sl_strategy strategy;
    bool low_discrepancy;
    sl_render_stats stats;     /* passes carry ref_rel_rmse */
} sl_converge_curve;

typedef struct sl_converge_report {
    sl_converge_curve curves[SL_CONVERGE_MAX];
    int count;
    int64_t reference_spp;     /* 0 when the reference was given */
    double reference_seconds;
} sl_converge_report;

/* Renders the scene with uniform, cosine, bsdf, light and mis (independent
 * random numbers) and mis+sobol (closed form off), then, when
 * base->closed_form, with the closed form ("closed-form": mis+sobol where
 * it samples), each up to base->spp samples per pixel,
 * measuring the relative RMSE after every pass against `reference` or, when
 * NULL, against a mis+sobol render of reference_spp samples. */
sl_result sl_converge_run(const sl_scene *scene, const sl_render_options *base,
                          const sl_image *reference, int64_t reference_spp,
                          sl_converge_report *rep, sl_error *err);
void sl_converge_report_free(sl_converge_report *rep);
/* Samples per pixel at which the curve first reaches `target` (log-log
 * interpolation between passes), or -1 if it never does. */
double sl_converge_spp_to_reach(const sl_converge_curve *c, double target);
/* Same, in seconds. */
double sl_converge_seconds_to_reach(const sl_converge_curve *c, double target);
/* Log-log plot of relative RMSE against seconds, one line per strategy. */
sl_result sl_converge_write_svg(const sl_converge_report *rep, const char *path, sl_error *err);
/* A Markdown table: strategy, spp, seconds, samples/s, final error, and the
 * spp and seconds each needs to reach `target`. */
sl_result sl_converge_write_table(const sl_converge_report *rep, double target, const char *path,
                                  sl_error *err);

/* Renders progressively until a stop condition holds. out gets an RGBA
 * image (alpha = coverage by the scene's shapes). Deterministic for a seed,
 * whatever the thread count. */
sl_result sl_render(const sl_scene *scene, const sl_render_options *o, sl_image *out,
                    sl_render_stats *stats, sl_error *err);

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_RENDER_H */
