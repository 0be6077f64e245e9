// SPDX-License-Identifier: BSD-3-Clause
// OpenCV's Hough circle transform behind a C function; candidates only, the
// sub-pixel fit and the decisions are in ball_detect.c.
#include <opencv2/imgproc.hpp>

#include <exception>
#include <vector>

extern "C" {
#include "unwrap_private.h"
}

extern "C" int ball_hough_cxx(const unsigned char *gray, int width, int height,
                              double min_radius, double max_radius, double min_dist, float *out,
                              int max_out)
{
    try {
        cv::Mat img(height, width, CV_8UC1, const_cast<unsigned char *>(gray));
        cv::Mat blurred;
        cv::GaussianBlur(img, blurred, cv::Size(5, 5), 1.5);
        std::vector<cv::Vec3f> circles;
        // A low accumulator threshold on purpose: false candidates are cheap,
        // the edge fit rejects them; a missed ball is not recoverable.
        cv::HoughCircles(blurred, circles, cv::HOUGH_GRADIENT, 1.0, min_dist, 100.0, 18.0,
                         (int)min_radius, (int)max_radius);
        int n = 0;
        for (const cv::Vec3f &c : circles) {
            if (n >= max_out)
                break;
            out[3 * n] = c[0];
            out[3 * n + 1] = c[1];
            out[3 * n + 2] = c[2];
            n++;
        }
        return n;
    } catch (const std::exception &) {
        return -1;
    }
}
