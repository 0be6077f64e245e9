// SPDX-License-Identifier: BSD-3-Clause
// OpenCV's solvers behind a C function, for test_merge_solve's comparison
// with the Debevec-Malik fit's own Cholesky (docs/merge.md).
#include <opencv2/core.hpp>

#include <exception>

extern "C" bool opencv_solve(double *a, double *b, int n, int method);

// method: 0 Cholesky, 1 LU, 2 SVD (cv::DECOMP_*). a is left as it was,
// b gets x.
extern "C" bool opencv_solve(double *a, double *b, int n, int method)
{
    static const int flags[3] = {cv::DECOMP_CHOLESKY, cv::DECOMP_LU, cv::DECOMP_SVD};
    try {
        cv::Mat x;
        if (!cv::solve(cv::Mat(n, n, CV_64F, a), cv::Mat(n, 1, CV_64F, b), x, flags[method]))
            return false;
        x.copyTo(cv::Mat(n, 1, CV_64F, b));
        return true;
    } catch (const std::exception &) {
        return false;
    }
}
