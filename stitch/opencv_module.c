/* SPDX-License-Identifier: BSD-3-Clause */
/* The OpenCV shims (ball_detect_cxx.cpp, chart_detect_cxx.cpp,
 * stitch_features_cxx.cpp, lens_calibrate_cxx.cpp) forward to the
 * setlight_opencv module, loaded on the first call: linked in, OpenCV's
 * ~26 libraries (mcc pulls dnn, protobuf, LAPACK, X11...) cost every
 * process ~11 ms of its ~17 ms start-up, though only ball and chart
 * detection, the stitch's features and lens-calibrate use them.
 * Sanitizer builds link the shims in instead. */
#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>

#include "calibrate_internal.h"
#include "lens_calibrate_private.h"
#include "stitch_private.h"
#include "unwrap_private.h"

#ifndef SETLIGHT_OPENCV_MODULE
#error "SETLIGHT_OPENCV_MODULE: path of the setlight_opencv module"
#endif

static int (*hough)(const unsigned char *, int, int, double, double, double, int, double, float *,
                    int);
static int (*mcc)(const unsigned char *, int, int, double[4][2], double *, char *, size_t);
static int (*chessboard)(const unsigned char *, int, int, int, int, float *, char *, size_t);
static int (*features)(const unsigned char *, const unsigned char *, int, int, int, int, float *,
                       unsigned char *, int *, char *, size_t);
static int (*match)(const unsigned char *, int, const unsigned char *, int, int, int, double, int *,
                    int, char *, size_t);
static char load_error[512];
static pthread_once_t load_once = PTHREAD_ONCE_INIT;

static void load(void)
{
    sl_log(SL_LOG_DEBUG, "starting OpenCV (%s)", SETLIGHT_OPENCV_MODULE);
    void *h = sl_module_open(SETLIGHT_OPENCV_MODULE);
    const char *why = h ? NULL : dlerror();
    if (h) {
        /* dlsym returns void *; POSIX guarantees it converts to a function pointer. */
        *(void **)&hough = dlsym(h, "sl_opencv_ball_hough");
        *(void **)&mcc = dlsym(h, "sl_opencv_mcc_detect");
        *(void **)&chessboard = dlsym(h, "sl_opencv_chessboard");
        *(void **)&features = dlsym(h, "sl_opencv_stitch_features");
        *(void **)&match = dlsym(h, "sl_opencv_stitch_match");
        if (!hough || !mcc || !chessboard || !features || !match)
            why = "entry points missing";
    }
    if (why) {
        snprintf(load_error, sizeof load_error, "cannot load the OpenCV module %s: %s",
                 SETLIGHT_OPENCV_MODULE, why);
        hough = NULL;
        mcc = NULL;
        chessboard = NULL;
        features = NULL;
        match = NULL;
    }
}

int ball_hough_cxx(const unsigned char *gray, int width, int height, double min_radius,
                   double max_radius, double min_dist, int kinds, double edge_threshold,
                   float *out, int max_out)
{
    pthread_once(&load_once, load);
    if (!hough) {
        /* The caller's one line says OpenCV failed; the reason is logged at debug level. */
        sl_log(SL_LOG_DEBUG, "%s", load_error);
        return -1;
    }
    return hough(gray, width, height, min_radius, max_radius, min_dist, kinds, edge_threshold, out,
                 max_out);
}

int sl_cal_mcc_detect(const unsigned char *bgr, int width, int height, double box[4][2],
                      double *cost, char *msg, size_t msg_size)
{
    pthread_once(&load_once, load);
    if (!mcc) {
        snprintf(msg, msg_size, "%s", load_error);
        return -1;
    }
    return mcc(bgr, width, height, box, cost, msg, msg_size);
}

int lens_chessboard_cxx(const unsigned char *gray, int width, int height, int cols, int rows,
                        float *corners, char *msg, size_t msg_size)
{
    pthread_once(&load_once, load);
    if (!chessboard) {
        snprintf(msg, msg_size, "%s", load_error);
        return -1;
    }
    return chessboard(gray, width, height, cols, rows, corners, msg, msg_size);
}

int stitch_features_cxx(const unsigned char *gray, const unsigned char *mask, int width,
                        int height, int detector, int max_out, float *xy, unsigned char *desc,
                        int *desc_bytes, char *msg, size_t msg_size)
{
    pthread_once(&load_once, load);
    if (!features) {
        snprintf(msg, msg_size, "%s", load_error);
        return -1;
    }
    return features(gray, mask, width, height, detector, max_out, xy, desc, desc_bytes, msg,
                    msg_size);
}

int stitch_match_cxx(const unsigned char *desc_a, int count_a, const unsigned char *desc_b,
                     int count_b, int desc_bytes, int detector, double ratio, int *pairs,
                     int max_out, char *msg, size_t msg_size)
{
    pthread_once(&load_once, load);
    if (!match) {
        snprintf(msg, msg_size, "%s", load_error);
        return -1;
    }
    return match(desc_a, count_a, desc_b, count_b, desc_bytes, detector, ratio, pairs, max_out,
                 msg, msg_size);
}
