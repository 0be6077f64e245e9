/* SPDX-License-Identifier: BSD-3-Clause */
/* Strip-by-strip image reading through OpenImageIO scanlines (see strip_reader.h). */
#include "strip_reader.h"

#include <OpenImageIO/imageio.h>

#include <cstring>
#include <memory>
#include <new>
#include <string>
#include <vector>

using OIIO::ImageInput;
using OIIO::ImageSpec;
using OIIO::TypeDesc;

struct merge_strip_reader {
    std::unique_ptr<ImageInput> in;
    std::string path;
    int width = 0, height = 0, channels = 0;
    std::vector<float> scratch;
};

namespace
{

std::string one_line(std::string s)
{
    if (s.size() > 200)
        s = s.substr(0, 200) + "...";
    for (char &c : s)
        if (c == '\n' || c == '\r')
            c = ' ';
    while (!s.empty() && s.back() == ' ')
        s.pop_back();
    return s.empty() ? std::string("no detail") : s;
}

} // namespace

extern "C" sl_result merge_strip_open(const char *path, merge_strip_reader **reader,
                                      merge_strip_info *info, sl_error *err)
{
    *reader = nullptr;
    std::memset(info, 0, sizeof *info);
    sl_result r = sl_check_input_file(path, err);
    if (r)
        return r;
    ImageSpec config;
    config.attribute("raw:ColorSpace", "sRGB-linear");
    config.attribute("raw:use_camera_wb", 1);
    config.attribute("raw:auto_bright", 0);
    config.attribute("raw:HighlightMode", 0);
    config.attribute("raw:apply_scene_linear_scale", 0);
    config.attribute("raw:user_flip", 0);
    merge_strip_reader *rd = new (std::nothrow) merge_strip_reader;
    if (!rd)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    rd->in = ImageInput::open(path, &config);
    if (!rd->in) {
        std::string why = one_line(OIIO::geterror());
        delete rd;
        return sl_error_set(err, SL_ERR_INPUT, "%s: not an image file OIIO can read (%s)", path,
                            why.c_str());
    }
    const ImageSpec &spec = rd->in->spec();
    if (spec.depth > 1 || spec.nchannels < 1) {
        delete rd;
        return sl_error_set(err, SL_ERR_INPUT, "%s: not a 2D image with colour channels", path);
    }
    rd->path = path;
    rd->width = spec.width;
    rd->height = spec.height;
    rd->channels = spec.nchannels >= 3 ? 3 : 1;
    info->width = spec.width;
    info->height = spec.height;
    info->file_channels = spec.nchannels;
    info->is_float = spec.format.basetype == TypeDesc::FLOAT ||
                     spec.format.basetype == TypeDesc::HALF ||
                     spec.format.basetype == TypeDesc::DOUBLE;
    info->bits = spec.get_int_attribute("oiio:BitsPerSample", (int)spec.format.size() * 8);
    *reader = rd;
    return SL_OK;
}

extern "C" sl_result merge_strip_read(merge_strip_reader *rd, int y0, int y1, float *rgb,
                                      sl_error *err)
{
    size_t n = (size_t)(y1 - y0) * (size_t)rd->width;
    float *dst = rgb;
    if (rd->channels == 1) {
        try {
            rd->scratch.resize(n);
        } catch (...) {
            return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", rd->path.c_str());
        }
        dst = rd->scratch.data();
    }
    /* Some readers (TIFF) report a short strip as an error yet return true. */
    if (!rd->in->read_scanlines(0, 0, y0, y1, 0, 0, rd->channels, TypeDesc::FLOAT, dst) ||
        rd->in->has_error()) {
        std::string why = one_line(rd->in->geterror());
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt image at rows %d-%d (%s)",
                            rd->path.c_str(), y0, y1 - 1, why.c_str());
    }
    if (rd->channels == 1)
        for (size_t i = 0; i < n; i++)
            rgb[3 * i] = rgb[3 * i + 1] = rgb[3 * i + 2] = dst[i];
    return SL_OK;
}

extern "C" void merge_strip_close(merge_strip_reader *rd)
{
    if (!rd)
        return;
    if (rd->in)
        rd->in->close();
    delete rd;
}
