// SPDX-License-Identifier: BSD-3-Clause
// OpenCV mcc behind a C function: finds the ColorChecker's box.
#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/mcc.hpp>

extern "C" {
#include "calibrate_internal.h"
}

extern "C" int sl_cal_mcc_detect(const unsigned char *bgr, int width, int height,
                                 double box[4][2], double *cost, char *msg, size_t msg_size)
{
    try {
        cv::Mat img(height, width, CV_8UC3, const_cast<unsigned char *>(bgr));
        cv::Ptr<cv::mcc::CCheckerDetector> det = cv::mcc::CCheckerDetector::create();
        if (!det->process(img, cv::mcc::MCC24, 1))
            return 0;
        cv::Ptr<cv::mcc::CChecker> best = det->getBestColorChecker();
        if (!best)
            return 0;
        std::vector<cv::Point2f> b = best->getBox();
        if (b.size() != 4)
            return 0;
        for (int i = 0; i < 4; i++) {
            box[i][0] = b[i].x;
            box[i][1] = b[i].y;
        }
        *cost = best->getCost();
        return 1;
    } catch (const std::exception &e) {
        std::snprintf(msg, msg_size, "%s", e.what());
        return -1;
    }
}
