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
        cv::GaussianBlur(img, blurred, cv::Size(0, 0), 1.5);
        // The accurate variant first (few, well-supported circles), then the
        // classic one with a low threshold so a ball in clutter still gets a
        // candidate; the edge fit in ball_detect.c decides.
        std::vector<cv::Vec3f> circles, more;
        cv::HoughCircles(blurred, circles, cv::HOUGH_GRADIENT_ALT, 1.5, min_dist, 150.0, 0.5,
                         (int)min_radius, (int)max_radius);
        cv::HoughCircles(blurred, more, cv::HOUGH_GRADIENT, 1.0, min_dist, 100.0, 18.0,
                         (int)min_radius, (int)max_radius);
        circles.insert(circles.end(), more.begin(), more.end());
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
