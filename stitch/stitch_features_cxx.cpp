// SPDX-License-Identifier: BSD-3-Clause
// OpenCV's SIFT / AKAZE detectors and a brute-force matcher behind C
// functions; the masks, the geometry and every decision are in
// stitch_solve*.c.
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cstdio>
#include <exception>
#include <vector>

extern "C" {
#include "stitch_private.h"
}

extern "C" int stitch_features_cxx(const unsigned char *gray, const unsigned char *mask,
                                   int width, int height, int detector, int max_out, float *xy,
                                   unsigned char *desc, int *desc_bytes, char *msg,
                                   size_t msg_size)
{
    try {
        cv::Mat img;
        // Local contrast (CLAHE): the texture of a wall or the ground is a
        // few codes of a log encoding that spans the sun and the shadows.
        cv::createCLAHE(3.0, cv::Size(8, 8))
            ->apply(cv::Mat(height, width, CV_8UC1, const_cast<unsigned char *>(gray)), img);
        cv::Mat m;
        if (mask)
            m = cv::Mat(height, width, CV_8UC1, const_cast<unsigned char *>(mask));
        cv::Ptr<cv::Feature2D> det;
        if (detector == STITCH_DETECT_AKAZE)
            det = cv::AKAZE::create(cv::AKAZE::DESCRIPTOR_MLDB, 0, 3, 0.0005f);
        else
            det = cv::SIFT::create(max_out, 3, 0.01);
        std::vector<cv::KeyPoint> kp;
        cv::Mat d;
        det->detectAndCompute(img, m, kp, d);
        // Strongest first, so a cap keeps the best.
        std::vector<int> order(kp.size());
        for (size_t i = 0; i < order.size(); i++)
            order[i] = (int)i;
        std::stable_sort(order.begin(), order.end(),
                         [&](int a, int b) { return kp[a].response > kp[b].response; });
        int n = std::min((int)order.size(), max_out);
        int bytes = d.cols;
        if (d.type() == CV_32F) {
            if (bytes > STITCH_DESC_MAX)
                return -1;
            for (int i = 0; i < n; i++) {
                const float *row = d.ptr<float>(order[i]);
                for (int j = 0; j < bytes; j++)
                    desc[(size_t)i * STITCH_DESC_MAX + j] =
                        (unsigned char)std::min(255.0f, std::max(0.0f, row[j] + 0.5f));
            }
        } else {
            if (bytes > STITCH_DESC_MAX)
                return -1;
            for (int i = 0; i < n; i++)
                std::copy(d.ptr<unsigned char>(order[i]), d.ptr<unsigned char>(order[i]) + bytes,
                          desc + (size_t)i * STITCH_DESC_MAX);
        }
        for (int i = 0; i < n; i++) {
            // OpenCV's keypoints are at pixel centres = integer coordinates.
            xy[2 * i] = kp[order[i]].pt.x + 0.5f;
            xy[2 * i + 1] = kp[order[i]].pt.y + 0.5f;
        }
        *desc_bytes = n > 0 ? bytes : (detector == STITCH_DETECT_AKAZE ? 61 : 128);
        return n;
    } catch (const std::exception &e) {
        std::snprintf(msg, msg_size, "OpenCV features: %s", e.what());
        return -1;
    }
}

static cv::Mat descriptors(const unsigned char *desc, int count, int bytes, int detector)
{
    cv::Mat packed(count, bytes, CV_8UC1);
    for (int i = 0; i < count; i++)
        std::copy(desc + (size_t)i * STITCH_DESC_MAX, desc + (size_t)i * STITCH_DESC_MAX + bytes,
                  packed.ptr<unsigned char>(i));
    if (detector == STITCH_DETECT_AKAZE)
        return packed;
    cv::Mat f;
    packed.convertTo(f, CV_32F);
    return f;
}

extern "C" int stitch_match_cxx(const unsigned char *desc_a, int count_a,
                                const unsigned char *desc_b, int count_b, int desc_bytes,
                                int detector, double ratio, int *pairs, int max_out, char *msg,
                                size_t msg_size)
{
    try {
        if (count_a < 2 || count_b < 2)
            return 0;
        cv::Mat a = descriptors(desc_a, count_a, desc_bytes, detector);
        cv::Mat b = descriptors(desc_b, count_b, desc_bytes, detector);
        cv::BFMatcher matcher(detector == STITCH_DETECT_AKAZE ? cv::NORM_HAMMING : cv::NORM_L2);
        std::vector<std::vector<cv::DMatch>> ab, ba;
        matcher.knnMatch(a, b, ab, 2);
        matcher.knnMatch(b, a, ba, 2);
        auto passes = [&](const std::vector<cv::DMatch> &m) {
            return m.size() == 2 ? m[0].distance < ratio * m[1].distance : m.size() == 1;
        };
        int n = 0;
        for (const auto &m : ab) {
            if (m.empty() || !passes(m) || n >= max_out)
                continue;
            const auto &back = ba[m[0].trainIdx];
            if (back.empty() || !passes(back) || back[0].trainIdx != m[0].queryIdx)
                continue;
            pairs[2 * n] = m[0].queryIdx;
            pairs[2 * n + 1] = m[0].trainIdx;
            n++;
        }
        return n;
    } catch (const std::exception &e) {
        std::snprintf(msg, msg_size, "OpenCV matching: %s", e.what());
        return -1;
    }
}
