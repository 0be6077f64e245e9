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
                              double min_radius, double max_radius, double min_dist, int kinds,
                              double edge_threshold, float *out, int max_out)
{
    try {
        cv::Mat img(height, width, CV_8UC1, const_cast<unsigned char *>(gray));
        cv::Mat blurred;
        cv::GaussianBlur(img, blurred, cv::Size(0, 0), 1.5);
        // Up to three lists, interleaved so a cap on the count starves none:
        // the accurate variant (few well-supported circles), the classic one
        // with centres at least a ball radius apart (one per region), and
        // the classic one with dense centres (a clutter peak next to the
        // ball must not hide it). Low thresholds on purpose: false candidates are cheap,
        // the edge fit rejects them; a missed ball is not recoverable.
        std::vector<cv::Vec3f> lists[3], circles;
        if (kinds & BALL_HOUGH_ALT)
            cv::HoughCircles(blurred, lists[0], cv::HOUGH_GRADIENT_ALT, 1.5, min_dist, 150.0, 0.5,
                             (int)min_radius, (int)max_radius);
        if (kinds & BALL_HOUGH_CLASSIC) {
            cv::HoughCircles(blurred, lists[1], cv::HOUGH_GRADIENT, 1.0, min_radius,
                             edge_threshold, 18.0, (int)min_radius, (int)max_radius);
            cv::HoughCircles(blurred, lists[2], cv::HOUGH_GRADIENT, 1.0, min_dist, edge_threshold,
                             18.0, (int)min_radius, (int)max_radius);
        }
        for (size_t i = 0; i < lists[1].size() || i < lists[2].size() || i < lists[0].size(); i++)
            for (const auto &l : lists)
                if (i < l.size())
                    circles.push_back(l[i]);
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
