// SPDX-License-Identifier: BSD-3-Clause
// OpenCV's chessboard finders behind a C function; the calibration itself is
// lens_calibrate.c's, on the project's own lens model.
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <vector>

extern "C" {
#include "lens_calibrate_private.h"
}

extern "C" int lens_chessboard_cxx(const unsigned char *gray, int width, int height, int cols,
                                   int rows, float *corners, char *msg, size_t msg_size)
{
    try {
        cv::Mat img(height, width, CV_8UC1, const_cast<unsigned char *>(gray));
        cv::Size pattern(cols, rows);
        std::vector<cv::Point2f> found;
        // The classic finder is ~20 times faster than the sector-based one;
        // the latter (more tolerant of blur and of a board bent by a fisheye
        // near its rim) is the fallback.
        bool ok = cv::findChessboardCorners(img, pattern, found,
                                            cv::CALIB_CB_ADAPTIVE_THRESH |
                                                cv::CALIB_CB_NORMALIZE_IMAGE |
                                                cv::CALIB_CB_FAST_CHECK);
        if (ok) {
            // Half the smallest corner spacing bounds the search window, so it
            // never reaches the next corner.
            double spacing = 1e9;
            for (int r = 0; r < rows; r++)
                for (int c = 0; c + 1 < cols; c++) {
                    cv::Point2f d = found[r * cols + c + 1] - found[r * cols + c];
                    spacing = std::min(spacing, (double)std::hypot(d.x, d.y));
                }
            int win = std::max(2, std::min(11, (int)(0.4 * spacing)));
            cv::cornerSubPix(img, found, cv::Size(win, win), cv::Size(-1, -1),
                             cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT,
                                              40, 0.01));
        } else {
            ok = cv::findChessboardCornersSB(img, pattern, found, cv::CALIB_CB_NORMALIZE_IMAGE);
        }
        if (!ok || (int)found.size() != cols * rows)
            return 0;
        for (size_t i = 0; i < found.size(); i++) {
            corners[2 * i] = found[i].x;
            corners[2 * i + 1] = found[i].y;
        }
        return 1;
    } catch (const std::exception &e) {
        snprintf(msg, msg_size, "OpenCV: %s", e.what());
        return -1;
    }
}
