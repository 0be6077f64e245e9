/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * setlight vset: the virtual film set. Scenes and their ground-truth
 * lat-longs, sky and sun, the simulated camera body, response and lenses,
 * probe photos (chrome ball, grey ball, chart), whole set captures, and the
 * virtual camera that the capture module opens as "virtual[:SCENE]" once
 * sl_vset_camera_register has run.
 */
#ifndef SETLIGHT_VSET_H
#define SETLIGHT_VSET_H

#include "setlight/capture.h"
#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/*
 * docs/virtual-set.md is the long form. Units: radiance is luminance-scaled
 * scene-linear Rec.709 (D65), 1.0 = 1 cd/m^2 of luminance. Directions use
 * the lat-long convention of core.h: azimuth 0 is +Z (the centre column),
 * azimuth 90 is +X (a quarter width in), elevation 90 is +Y.
 */

#define SL_VSET_MAX_LIGHTS 32
#define SL_VSET_SMALL_WIDTH 1024
#define SL_VSET_FULL_WIDTH 4096

typedef enum {
    SL_VSET_BG_SKY = 0, /* Preetham daylight sky over a textured ground */
    SL_VSET_BG_ROOM,    /* a box room with textured walls, floor and ceiling */
    SL_VSET_BG_DARK     /* dark surroundings: L = dark * (1 + 0.5 y) */
} sl_vset_background;

typedef enum {
    SL_VSET_SHAPE_DISK = 0, /* spherical cap; width_deg is its angular diameter */
    SL_VSET_SHAPE_RECT      /* a flat rectangle facing the camera (gnomonic) */
} sl_vset_shape;

typedef enum {
    SL_VSET_EMIT_UNIFORM = 0, /* constant radiance: colour * luminance */
    SL_VSET_EMIT_SUN,         /* disk whose radiance comes from the sky model */
    SL_VSET_EMIT_WINDOW       /* shows the daylight exterior, times transmission */
} sl_vset_emit;

typedef struct sl_vset_light {
    char name[64];
    sl_vset_shape shape;
    sl_vset_emit emit;
    double azimuth_deg, elevation_deg; /* centre */
    double width_deg, height_deg;      /* rect: full angular extents; disk: diameter */
    double roll_deg;                   /* rect: rotation about its centre direction */
    double kelvin;                     /* > 0: colour of a black body; else rgb */
    double rgb[3];                     /* colour, rescaled to luminance 1 */
    double luminance;                  /* cd/m^2 (uniform); transmission (window) */
    /* Filled by sl_vset_scene_make: */
    double dir[3];       /* unit direction of the centre */
    double solid_angle;  /* exact, steradians */
    double radiance[3];  /* mean radiance over the light */
    double integral[3];  /* integral of L over the light's solid angle */
} sl_vset_light;

typedef struct sl_vset_desc {
    char name[64];
    sl_vset_background background;
    /* Daylight (sky background and what windows look out on). The sun
     * position comes from the light with emit SL_VSET_EMIT_SUN when there
     * is one, else from these two. */
    double sun_azimuth_deg, sun_elevation_deg;
    double turbidity;     /* Preetham, 2..10 */
    double ground_albedo; /* mean ground albedo, 0..1 */
    double room_illuminance; /* lux falling on room walls */
    double dark_luminance;   /* dark background level, cd/m^2 */
    int light_count;
    sl_vset_light lights[SL_VSET_MAX_LIGHTS];
} sl_vset_desc;

typedef struct sl_vset_scene {
    sl_vset_desc desc;  /* with the lights' computed fields filled */
    sl_image latlong;   /* RGB float, width x width/2 */
    double total[3];    /* integral of L over the sphere, from the texels */
} sl_vset_scene;

/* Names of the built-in scenes, NULL-terminated: "exterior", "stage", "night". */
const char *const *sl_vset_preset_names(void);
/* SL_ERR_USAGE naming the scene when unknown. */
sl_result sl_vset_preset(const char *name, sl_vset_desc *desc, sl_error *err);
/* Reads a scene JSON file (format in docs/virtual-set.md). SL_ERR_NOT_FOUND
 * when missing, SL_ERR_INPUT naming the file and the field when malformed. */
sl_result sl_vset_desc_read_json(const char *path, sl_vset_desc *desc, sl_error *err);
/* Checks every value of a description; SL_ERR_INPUT naming the field. */
sl_result sl_vset_desc_validate(const sl_vset_desc *desc, sl_error *err);

/* Builds the ground-truth lat-long of `width` (even, >= 16) and fills the
 * lights' directions, solid angles, radiances and integrals. Light edges
 * are antialiased by exact-area supersampling of the texels they touch. */
sl_result sl_vset_scene_make(const sl_vset_desc *desc, int width, sl_vset_scene *scene,
                             sl_error *err);
void sl_vset_scene_free(sl_vset_scene *scene);
/* The lat-long's solid-angle-weighted log-average Rec.709 luminance (each
 * texel floored at 1e-6): what a meter reads, and the exposure the virtual
 * camera centres its bracket on. */
double sl_vset_log_average(const sl_image *latlong);
/* One light alone on black, as it appears in the scene's lat-long of
 * `width`: for checking integrals and as a ground-truth mask. */
sl_result sl_vset_light_image(const sl_vset_desc *desc, int index, int width, sl_image *out,
                              sl_error *err);
/* The lights as JSON (truth/lights.json); caller frees with free(). */
char *sl_vset_lights_json(const sl_vset_scene *scene);

/* Linear Rec.709 colour of a black body, scaled to luminance 1
 * (1667..25000 K, Kim et al. Planckian-locus fit; out-of-gamut parts clipped). */
void sl_vset_kelvin_rgb(double kelvin, double rgb[3]);
/* Sun radiance (linear Rec.709, cd/m^2-scaled) seen at the ground for a sun
 * elevation and turbidity: extraterrestrial disk dimmed by Rayleigh and
 * aerosol extinction along the Kasten-Young air mass. */
void sl_vset_sun_radiance(double elevation_deg, double turbidity, double rgb[3]);
/* Preetham sky radiance for a view direction, without the sun disk. */
void sl_vset_sky_radiance(const double sun_dir[3], double turbidity, const double dir[3],
                          double rgb[3]);

/* ---- camera response ---------------------------------------------- */

#define SL_VSET_CRF_SAMPLES 1024

/* A monotonic response: out = curve(in), in and out in [0, 1], sampled at
 * in = i / (SL_VSET_CRF_SAMPLES - 1) and linearly interpolated. */
typedef struct sl_vset_response {
    char name[128];
    double curve[SL_VSET_CRF_SAMPLES];
} sl_vset_response;

/* "linear", "srgb", "filmic", "canon"; NULL-terminated. */
const char *const *sl_vset_response_names(void);
sl_result sl_vset_response_preset(const char *name, sl_vset_response *resp, sl_error *err);
/* A curve file: the DoRF database format (name, type, "I =", samples,
 * "B =", samples; `curve_name` picks one, NULL the first) or plain text
 * with "I B" per line. The curve is resampled and made monotonic. */
sl_result sl_vset_response_load(const char *path, const char *curve_name,
                                sl_vset_response *resp, sl_error *err);
double sl_vset_response_apply(const sl_vset_response *resp, double x);
/* Inverse: the smallest in with curve(in) >= y, interpolated. */
double sl_vset_response_invert(const sl_vset_response *resp, double y);
/* d curve / d in at x (from the table). */
double sl_vset_response_slope(const sl_vset_response *resp, double x);

/* ---- camera body ---------------------------------------------------- */

typedef struct sl_vset_exposure {
    double time_s;
    double f_number;
    double iso;
} sl_vset_exposure;

typedef struct sl_vset_camera {
    char make[64];
    char model[64];
    /* Sensor: relative exposure X = L * t * (ISO/100) * k / N^2, X = 1 at
     * raw saturation. k follows ISO 12232 saturation speed, k = 100 q / 78,
     * q = 0.65 (lens transmission and cos^4 at the centre). */
    double k;
    double full_well_e;     /* electrons at raw saturation, base ISO 100 */
    double read_noise_pre_e;  /* before the ISO gain, electrons */
    double read_noise_post_e; /* after the ISO gain, electrons at ISO 100 */
    int raw_bits;             /* 12 or 14 */
    /* Colour: sensor RGB = cam_from_rec709 * L (green row sums to 1);
     * output linear = ccm * min(diag(wb) * sensor RGB, 1). */
    double cam_from_rec709[3][3];
    double wb[3];
    double ccm[3][3];
    sl_vset_response response;
} sl_vset_camera;

/* A full-frame body modelled on the Canon EOS 5D Mark II (Adobe DNG
 * ColorMatrix2), white balance `wb_kelvin` (e.g. 5500 daylight, 3200
 * tungsten), response "canon". */
void sl_vset_camera_default(sl_vset_camera *cam, double wb_kelvin);
/* t * (ISO/100) * k / N^2 */
double sl_vset_exposure_scale(const sl_vset_camera *cam, const sl_vset_exposure *e);
/* Standard deviation of the raw value X (X = 1 at saturation) at mean X,
 * at this ISO: Poisson shot noise plus Gaussian read noise. */
double sl_vset_sensor_noise_std(const sl_vset_camera *cam, double iso, double x);
/* The 3x3 from scene radiance (Rec.709) to output linear RGB:
 * ccm * diag(wb) * cam_from_rec709. */
void sl_vset_camera_output_matrix(const sl_vset_camera *cam, double m[3][3]);

typedef struct sl_vset_shot {
    sl_image sensor; /* raw X in camera RGB, black subtracted (read noise may go a little
                        below 0), clipped at 1, quantised to raw_bits */
    sl_image linear; /* white-balanced, colour-corrected, clipped to [0,1] */
    sl_image encoded; /* response applied to linear, not yet quantised */
} sl_vset_shot;

/* Photographs `radiance` (Rec.709 at the sensor, vignetting included):
 * exposure, Poisson-Gaussian noise from `seed` (each pixel's noise depends
 * only on seed and position), raw clipping and quantisation, white balance,
 * colour matrix and response. */
sl_result sl_vset_camera_shoot(const sl_vset_camera *cam, const sl_vset_exposure *e,
                               const sl_image *radiance, uint64_t seed, sl_vset_shot *shot,
                               sl_error *err);
void sl_vset_shot_free(sl_vset_shot *shot);
/* Rounds every sample to the nearest of 2^bits - 1 levels in [0, 1]. */
void sl_vset_quantize(sl_image *img, int bits);

/* ---- lenses --------------------------------------------------------- */

/* The probes' long lens; the HDRI fisheye is an sl_lens (below). */
typedef enum {
    SL_VSET_LENS_RECTILINEAR = 0 /* r = f tan(theta) */
} sl_vset_lens_type;

typedef struct sl_vset_lens {
    char name[128];
    sl_vset_lens_type type;
    double focal_mm;
    double sensor_width_mm; /* the image's width; pixels are square */
    /* Optical vignetting: gain 1 + a rho^2 + b rho^4, rho = r / half
     * diagonal, times natural cos^4(theta). */
    double vignette_a, vignette_b;
} sl_vset_lens;

/* Where the camera points: yaw = azimuth of the optical axis, pitch =
 * elevation, roll about the axis (degrees). Image right at yaw 0 is -X. */
typedef struct sl_vset_view {
    double yaw_deg, pitch_deg, roll_deg;
} sl_vset_view;

/* Rectilinear lens of focal_mm on a 36 mm wide sensor. */
void sl_vset_lens_rectilinear(sl_vset_lens *lens, double focal_mm);

/* Direction seen at image position (x, y) in pixels (0,0 = top-left
 * corner of the top-left pixel) of a width x height image. */
bool sl_vset_lens_to_dir(const sl_vset_lens *lens, const sl_vset_view *view, int width,
                         int height, double x, double y, double dir[3]);
/* Inverse; false when the direction is outside the lens's field. */
bool sl_vset_lens_from_dir(const sl_vset_lens *lens, const sl_vset_view *view, int width,
                           int height, const double dir[3], double *x, double *y);
/* Vignetting gain at image position (x, y). */
double sl_vset_lens_vignette(const sl_vset_lens *lens, int width, int height, double x,
                             double y);

/* Radiance image of an environment at infinity through any lens of the
 * core model (projection, correction, off-centre axis, its vignetting
 * gain) pointing at pose: lens->width x lens->height, ss x ss samples per
 * pixel, bilinear lookups, black where the lens sees nothing. The stitch's
 * tests and the fisheye views of the virtual set are made with it. */
sl_result sl_vset_view_image(const sl_lens *lens, const sl_view_pose *pose,
                             const sl_image *latlong, int ss, sl_image *out, sl_error *err);

/* The HDRI fisheye of the virtual set: what its EXIF states (nominal) and
 * what the glass really is (true), for a width x height frame on the 36 mm
 * wide sensor. Nominal: 8 mm equisolid, centre at the frame's centre, no
 * correction, no falloff. True: focal 8.12 mm (1.5% long), optical centre
 * +0.6% and -0.4% of the width off the frame's centre, radial correction
 * k1 = 0.02, k2 = -0.01, vignetting v1 = -0.034, v2 = -0.003 (a 8% falloff
 * at the circle), max field 90 deg; circle_radius_px where theta = 90 deg. */
#define SL_VSET_FISHEYE_NAME "8mm f/3.5 equisolid fisheye"
#define SL_VSET_FISHEYE_FOCAL_MM 8.0
#define SL_VSET_SENSOR_WIDTH_MM 36.0
void sl_vset_fisheye_nominal(sl_lens *lens, int width, int height);
void sl_vset_fisheye_true(sl_lens *lens, int width, int height);
/* The nodal head's true pose of view `view` of a capture whose plan is
 * `plan`: view 0 is exact (it defines the frame of the truth lat-long);
 * every other view's yaw is off by 0.5-1 deg and its pitch and roll by
 * 0.3-0.5 deg, signs and sizes from the seed. A zenith view (pitch 90)
 * tilts down from the zenith. */
void sl_vset_head_pose(uint64_t seed, int view, const sl_view_pose *plan, sl_view_pose *out);

/* ---- probes: chrome ball, grey ball and chart ------------------------ */

typedef enum {
    SL_VSET_PROBE_CHROME = 0, /* polished chrome ball: render's sl_material_chrome (a mirror) */
    SL_VSET_PROBE_GREY,       /* 18% grey Lambertian ball */
    SL_VSET_PROBE_CHART       /* ColorChecker Classic 24 facing the camera */
} sl_vset_probe_kind;

/* A probe photographed from the capture point (the world origin) with a
 * long lens: the ball's or chart's centre sits on the optical axis at
 * distance_m, lit by the set's lat-long at infinity (which the render
 * also shows behind it). */
typedef struct sl_vset_probe {
    sl_vset_probe_kind kind;
    sl_vset_lens lens;  /* rectilinear */
    sl_vset_view view;  /* the camera direction */
    double distance_m;
    double size_m;      /* ball diameter, or the chart's frame width */
    int width, height;
    int64_t spp;        /* render samples per pixel */
    uint64_t seed;
} sl_vset_probe;

/* Where the probe lands in the photo, and how the render went. */
typedef struct sl_vset_probe_geometry {
    double focal_px;             /* focal_mm * width / sensor_width_mm */
    double cx, cy, r;            /* ball outline, pixels (on axis: an exact circle) */
    double ball_angle_deg;       /* ball's angular radius seen from the camera */
    double patch_centers[24][2]; /* chart, chart order */
    double corners[4][2];        /* chart: centres of patches 1, 6, 24, 19 */
    double outline[4][2];        /* chart frame corners, clockwise from the top left */
    int64_t spp;
    double render_rel_rmse;      /* the renderer's estimate of its relative RMSE */
    double seconds;
} sl_vset_probe_geometry;

/* "chrome", "grey", "chart". */
const char *sl_vset_probe_name(sl_vset_probe_kind kind);
/* A 200 mm lens (vignetting -3% at the corner, plus cos^4) looking along
 * azimuth 180 from 2 m: a 100 mm ball, or a 250 mm wide chart. */
void sl_vset_probe_default(sl_vset_probe *p, sl_vset_probe_kind kind, int width, int height);
/* Renders the probe under `latlong` (Rec.709 radiance) with render/'s
 * perspective camera and applies the lens's vignetting: `radiance` gets the
 * RGB image at the sensor, ready for sl_vset_camera_shoot. The chart, flat
 * under a set at infinity, gets one irradiance summed over the lat-long
 * (noise-free; the render gives what each pixel sees). geo may be NULL. */
sl_result sl_vset_probe_render(const sl_vset_probe *p, const sl_image *latlong,
                               sl_image *radiance, sl_vset_probe_geometry *geo, sl_error *err);
/* RGB irradiance on a flat surface facing `n` (unit) under a lat-long at
 * infinity: every texel's radiance times its cosine and solid angle. The
 * light a chart facing n receives, as the probe render lights it. */
void sl_vset_irradiance(const sl_image *latlong, const double n[3], double e[3]);

/* ---- set captures ---------------------------------------------------- */

/* What the simulated data wrangler shoots: an HDRI bracket (`brackets`
 * exposures `stops` apart, centred by metering the scene) for each of
 * `views` fisheye views on a nodal head (plus the zenith if asked), every
 * frame written as a camera would (JPEG, 16-bit TIFF, linear 16-bit TIFF,
 * EXIF), with the ground truth in truth/. docs/virtual-set.md has the layout. */
typedef struct sl_vset_capture_opts {
    sl_vset_desc scene;
    int latlong_width;             /* ground truth resolution */
    int photo_width, photo_height; /* frame size */
    int supersample;               /* per side, for the lens image */
    uint64_t seed;
    int views;                     /* around the horizon, 360/views apart */
    bool zenith;
    int brackets;
    double stops;                  /* whole stops, on the camera's full-stop shutter scale */
    double f_number, iso, wb_kelvin;
    sl_vset_response response;     /* the camera's curve (default "canon") */
    int raw_bits;                  /* 12 or 14 (default) */
    double jitter_deg;             /* std of per-frame yaw, pitch, roll wander (hand-held) */
    bool ghost;                    /* a person walks across the first view between frames */
    bool force;                    /* replace a capture already in the folder */
    /* Probe photos (chrome ball, grey ball, chart) with a long lens: the
     * chrome ball bracketed like the HDRI, the others 3 exposures 2 stops
     * apart. probe_width 0: no probes. Samples per pixel: the chrome ball
     * and the chart need them for antialiasing only (a mirror and a flat
     * chart render without noise), the grey ball for its lighting. */
    int probe_width, probe_height;
    int64_t probe_spp_aa, probe_spp_grey;
} sl_vset_capture_opts;

typedef enum {
    SL_VSET_SIZE_TINY = 0, /* 256 lat-long, 192x128 frames: tests and quick looks */
    SL_VSET_SIZE_SMALL,    /* 1024 lat-long, 720x480 frames */
    SL_VSET_SIZE_FULL      /* 4096 lat-long, 3000x2000 frames */
} sl_vset_size;

/* "tiny", "small", "full"; -1 if unknown. */
int sl_vset_size_from_name(const char *name);

/* Defaults for a scene at a size: 3 views, 7 exposures 3 stops apart;
 * aperture, ISO and white balance as a wrangler would set them for
 * daylight, stage or night. */
void sl_vset_capture_defaults(sl_vset_capture_opts *o, const sl_vset_desc *scene,
                              sl_vset_size size);

typedef struct sl_vset_capture_summary {
    int frames;        /* HDRI frames */
    int probe_frames;  /* chrome ball, grey ball and chart frames */
    int views;
    double center_time_s;  /* metered exposure at the bracket centre */
    double min_time_s, max_time_s;
    double f_number, iso;
} sl_vset_capture_summary;

/* Writes the capture folder `dir`. It is assembled in a temporary sibling
 * and renamed into place, so a failure leaves nothing behind. An existing
 * empty folder is filled; one holding a capture (capture.json) is replaced
 * only with `force` (else SL_ERR_USAGE); any other non-empty folder is
 * refused (SL_ERR_USAGE). */
sl_result sl_vset_capture_write(const sl_vset_capture_opts *o, const char *dir,
                                sl_vset_capture_summary *summary, sl_error *err);

/* ---- scoring: what `setlight process` made of a capture, against its truth */

/* Luminance of a test image against the truth, up to the one free scale of
 * relative units: scale is the median of test / truth over the pixels
 * compared, median and p95 are of |test / (scale truth) - 1|, power is the
 * summed luminance of test / scale over the truth's (lat-longs: over the
 * whole sphere, solid-angle weighted). */
typedef struct sl_vset_image_score {
    double scale, median, p95, power;
    double solid_angle_sr; /* lat-longs: of the texels compared */
    int64_t pixels;        /* pixels or texels compared */
} sl_vset_image_score;

/* A lat-long against the truth lat-long (looked up bilinearly at each test
 * texel's direction), over the texels within band_deg of the horizon, in
 * the hemisphere around `toward` when not NULL, and seen (alpha > 0) when
 * the test has 4 channels. rec709_from_test (NULL: none) takes the test's
 * RGB to Rec.709 first (a camera's output space). */
sl_result sl_vset_score_latlong(const sl_image *test, const double rec709_from_test[3][3],
                                const sl_image *truth, double band_deg, const double toward[3],
                                sl_vset_image_score *out, sl_error *err);
/* An image against a truth image of its size, pixel by pixel: a merged
 * photo against the radiance its frames saw. Pixels flagged in `clipped`
 * (any channel > 0; may be NULL) or dark in the truth are not compared. */
sl_result sl_vset_score_image(const sl_image *test, const double rec709_from_test[3][3],
                              const sl_image *truth, const sl_image *clipped,
                              sl_vset_image_score *out, sl_error *err);

/* A rig (rig.json) against the true lamps (truth/lights.json): each lamp
 * matched to the rig light nearest in direction when within match_deg;
 * a rig light's power (luminance integral / scale, scale the rig's map over
 * the truth) against the sum of the lamps it took. white: per channel gains
 * that take the lamps to the white the rig's map was balanced to (a chart
 * calibration's: the truth's white_gain), NULL for the lamps as they are;
 * scale is then the map over the truth in that white. */
typedef struct sl_vset_rig_score {
    int truth_lights, rig_lights, matched;
    double direction_mean_deg, direction_worst_deg; /* of the matched lamps */
    double power_median, power_worst;               /* over the rig lights that took lamps */
} sl_vset_rig_score;
sl_result sl_vset_score_rig(const char *rig_json, const char *lights_json, double scale,
                            const double white[3], double match_deg, sl_vset_rig_score *out,
                            sl_error *err);

/* What `setlight demo` holds each stage to (docs/virtual-set.md, "The
 * demo"): what a right pipeline gives on the virtual set, with a margin.
 * Errors are after the free scale of relative units; lat-longs within the
 * band of the horizon. */
#define SL_VSET_SCORE_BAND_DEG 60.0
#define SL_VSET_SCORE_MATCH_DEG 5.0          /* a rig light this near a lamp is that lamp */
#define SL_VSET_TOL_MERGE_MEDIAN 0.05        /* each merge against its truth radiance */
#define SL_VSET_TOL_MERGE_SCALE_SPREAD 1.10  /* largest / smallest scale of the fisheye views'
                                                merges: the stitch blends them as they are */
#define SL_VSET_TOL_LATLONG_MEDIAN 0.15      /* stitched and calibrated lat-longs */
#define SL_VSET_TOL_LATLONG_P95 1.0
#define SL_VSET_TOL_POWER 0.25               /* |power ratio - 1| */
#define SL_VSET_TOL_UNWRAP_MEDIAN 0.15       /* chrome-ball unwrap, the half it sees */
#define SL_VSET_TOL_BALANCE 0.05             /* calibrated channel balance in its white, |b - 1| */
#define SL_VSET_TOL_ABSOLUTE 0.10            /* calibrated scale, when in absolute units */
#define SL_VSET_TOL_EXPOSURE 0.05            /* calibrated map / truth against the grey ball's
                                                merge / truth: the units it is tied to */
#define SL_VSET_TOL_RIG_MATCHED 0.5          /* share of the lamps the rig must find */
#define SL_VSET_TOL_RIG_DIRECTION_DEG 4.0    /* worst matched lamp's direction */
#define SL_VSET_TOL_RIG_POWER 0.5            /* |median power ratio - 1| */
#define SL_VSET_TOL_RENDER_RMSE 0.10         /* grey and chart renders against the truth's */
#define SL_VSET_TOL_RENDER_CHROME_RMSE 0.60  /* the chrome ball: every edge of the map shows */

typedef struct sl_vset_score_options {
    const char *capture;        /* the capture folder `setlight simulate` wrote */
    const char *jobs_json;      /* the process's graph (OUT/jobs.json): which job made what */
    const char *setup;          /* the setup's name in it */
    const char *process_json;   /* the process's --json result (the cost), or NULL */
    const char *process_report; /* its report page, named in ours, or NULL */
    const char *report_dir;     /* write report.html there, or NULL */
    const char *json_path;      /* write the result's json there (atomically), or NULL */
    double simulate_seconds, simulate_cpu_seconds; /* the capture's cost */
    double band_deg;            /* SL_VSET_SCORE_BAND_DEG */
    int64_t truth_spp;          /* the truth renders' samples per pixel (128) */
    uint64_t seed;              /* theirs (1) */
} sl_vset_score_options;

void sl_vset_score_options_init(sl_vset_score_options *o);

typedef struct sl_vset_score_result {
    int stages, stages_failed; /* stages scored, those outside their tolerances */
    char *json;    /* one document: every stage's numbers, tolerances, verdict, cost */
    char *summary; /* a line per stage, for people */
} sl_vset_score_result;

/* Scores every stage the process ran on the setup: merges (each view
 * through the true lens and head, each probe's render), stitch and
 * calibrate (lat-long against the truth; the calibration's scale and
 * channel balance), the chrome-ball unwrap, the rig against the lamps, the
 * validation renders against the scenes rendered under the truth. A stage
 * outside its tolerances is a verdict (stages_failed), not an error; a
 * missing or unreadable output is (SL_ERR_INPUT or SL_ERR_NOT_FOUND naming
 * it). */
sl_result sl_vset_score_setup(const sl_vset_score_options *o, sl_vset_score_result *res,
                              sl_error *err);
void sl_vset_score_result_free(sl_vset_score_result *res);

/* ---- the virtual camera ---------------------------------------------- */

/* The virtual set's camera: photographs a virtual scene (sl_vset_*) through
 * the 8 mm fisheye on a nodal head that turns 360/views degrees per view,
 * with the simulated body (noise, 14-bit raw, sRGB-encoded JPEG) and EXIF
 * like a real camera's (exposure, date with SubSecTimeOriginal on a virtual
 * clock: 0.2 s between frames plus the exposure, 15 s per head turn). It
 * offers third-stop shutter speeds 1/8000..30 s, f/2.8..22, ISO 100..3200;
 * it starts metered for the scene. Faults, for tests, are off when 0. */
typedef struct sl_virtual_camera_opts {
    char scene[512];          /* preset name or scene JSON path; "" = "stage" */
    int width, height;        /* frame size (0: 360 x 240) */
    uint64_t seed;            /* sensor noise (0: 1) */
    int busy, busy_at;        /* answer `busy` triggers from frame busy_at (1-based) busy */
    int ignore_shutter;       /* the k-th shutter change is acknowledged, not applied */
    bool exif_lies;           /* ...and the file's EXIF shows the requested speed */
    double refuse_shutter;    /* a shutter speed (s) the camera refuses to set */
    int drop_after;           /* the connection drops at the trigger of frame N+1 */
    int down_attempts;        /* reconnections refused after the drop (-1: all) */
    int ignore_format;        /* the k-th image-format change is acknowledged, not applied */
    bool format_lies;         /* ...and the setting reads back as changed */
    int drop_before_raw;      /* raw+jpeg: the connection drops after frame N's JPEG */
    int drop_at;              /* the connection drops at the trigger of frame N (1-based,
                                 so also before the first; drop_after N-1 otherwise) */
} sl_virtual_camera_opts;
/* Opens the virtual camera with these options (no registration needed). */
sl_result sl_camera_open_virtual(const sl_virtual_camera_opts *o, sl_camera **camera,
                                 sl_error *err);
/* Adds the virtual camera to capture's backend table, so sl_camera_open
 * opens "virtual" and "virtual:SCENE" (a preset or a scene JSON file,
 * default "stage"). Call once at start-up; a second call does nothing. */
sl_result sl_vset_camera_register(sl_error *err);

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_VSET_H */
