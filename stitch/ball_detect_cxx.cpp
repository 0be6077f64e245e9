// SPDX-License-Identifier: BSD-3-Clause
// OpenCV's Hough circle transform behind a C function; candidates only, the
// sub-pixel fit and the decisions are in ball_detect.c.
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
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
            // The classic transform estimates a radius for every centre over
            // its accumulator threshold (its cost: centres times edge pixels),
            // then drops centres nearer than min_dist to a stronger one. One
            // run with the dense spacing, thinned by the same rule to the
            // sparse one, gives both lists (the sparse one as a run of its
            // own would, but for centres whose dense neighbour it dropped).
            // A circle of the smallest radius sought has 2 pi r edge pixels
            // voting; centres with under 30% of that are clutter.
            double votes = std::max(18.0, 0.3 * 2.0 * M_PI * min_radius);
            cv::HoughCircles(blurred, lists[2], cv::HOUGH_GRADIENT, 1.0, min_dist, edge_threshold,
                             votes, (int)min_radius, (int)max_radius);
            const float sparse2 = (float)(min_radius * min_radius);
            for (const cv::Vec3f &c : lists[2]) {
                bool near = false;
                for (const cv::Vec3f &k : lists[1])
                    near = near || (c[0] - k[0]) * (c[0] - k[0]) + (c[1] - k[1]) * (c[1] - k[1]) <
                                       sparse2;
                if (!near)
                    lists[1].push_back(c);
            }
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
