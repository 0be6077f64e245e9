// SPDX-License-Identifier: BSD-3-Clause
// OpenEXR's C++ library behind C functions, for test_exr_layouts: it writes
// every compression OpenEXR 3.1 has (the 3.1 C API cannot encode DWAA/DWAB),
// subsampled channels and tiles, and decodes a channel as the reference the
// reader's pixels are compared with.
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfRgbaFile.h>
#include <ImfTiledOutputFile.h>
#include <half.h>

#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "exr_layouts.h"

namespace {

// Runs f; false with the library's message in why when it throws.
template <class F> bool guarded(F f, char *why, size_t size)
{
    std::string what = "unknown exception";
    try {
        f();
        return true;
    } catch (const std::exception &e) {
        what = e.what();
    } catch (...) {
    }
    if (why && size)
        std::snprintf(why, size, "%s", what.c_str());
    return false;
}

} // namespace

extern "C" bool exr_layout_write(const char *path, const exr_layout *l, exr_layout_value value,
                                 char *why, size_t why_size)
{
    return guarded([&] {
        Imath::Box2i data(Imath::V2i(l->data_x, l->data_y),
                          Imath::V2i(l->data_x + l->width - 1, l->data_y + l->height - 1));
        Imath::Box2i display = data;
        if (l->display_w > 0)
            display = Imath::Box2i(Imath::V2i(0, 0), Imath::V2i(l->display_w - 1, l->display_h - 1));
        Imf::Header header(display, data);
        header.compression() = (Imf::Compression)l->compression;
        // Written from buffers of the channel's own type (OutputFile does not convert).
        std::vector<std::vector<float>> planes((size_t)l->nch);
        std::vector<std::vector<half>> halves((size_t)l->nch);
        Imf::FrameBuffer fb;
        for (int c = 0; c < l->nch; c++) {
            const exr_layout_channel &ch = l->channels[c];
            int xs = ch.sampling ? ch.sampling : 1, sw = l->width / xs, sh = l->height / xs;
            header.channels().insert(ch.name, Imf::Channel((Imf::PixelType)ch.type, xs, xs));
            std::vector<float> &p = planes[(size_t)c];
            p.resize((size_t)sw * (size_t)sh);
            for (int y = 0; y < sh; y++)
                for (int x = 0; x < sw; x++)
                    p[(size_t)y * (size_t)sw + (size_t)x] =
                        value(c, l->data_x + x * xs, l->data_y + y * xs);
            if (ch.type == Imf::HALF) {
                std::vector<half> &hp = halves[(size_t)c];
                hp.assign(p.begin(), p.end());
                fb.insert(ch.name, Imf::Slice::Make(Imf::HALF, hp.data(), data, sizeof(half),
                                                    sizeof(half) * (size_t)sw, xs, xs));
            } else {
                fb.insert(ch.name, Imf::Slice::Make(Imf::FLOAT, p.data(), data, sizeof(float),
                                                    sizeof(float) * (size_t)sw, xs, xs));
            }
        }
        if (l->tile) {
            header.setTileDescription(Imf::TileDescription(l->tile, l->tile, Imf::ONE_LEVEL));
            Imf::TiledOutputFile out(path, header);
            out.setFrameBuffer(fb);
            out.writeTiles(0, out.numXTiles() - 1, 0, out.numYTiles() - 1);
        } else {
            Imf::OutputFile out(path, header);
            out.setFrameBuffer(fb);
            out.writePixels(l->height);
        }
    }, why, why_size);
}

extern "C" bool exr_layout_decode(const char *path, const char *name, float *out, int width,
                                  int height, char *why, size_t why_size)
{
    return guarded([&] {
        Imf::InputFile in(path);
        const Imath::Box2i &data = in.header().dataWindow();
        Imf::FrameBuffer fb;
        fb.insert(name, Imf::Slice::Make(Imf::FLOAT, out, data, sizeof(float),
                                         sizeof(float) * (size_t)width));
        in.setFrameBuffer(fb);
        in.readPixels(data.min.y, data.min.y + height - 1);
    }, why, why_size);
}

extern "C" bool exr_layout_write_yc(const char *path, const float *pixels, int width, int height,
                                    int channels, char *why, size_t why_size)
{
    return guarded([&] {
        std::vector<Imf::Rgba> px((size_t)width * (size_t)height);
        for (size_t i = 0; i < px.size(); i++) {
            const float *p = pixels + i * (size_t)channels;
            px[i] = Imf::Rgba(p[0], p[1], p[2], channels == 4 ? p[3] : 1.0f);
        }
        Imf::RgbaOutputFile out(path, width, height, channels == 4 ? Imf::WRITE_YCA : Imf::WRITE_YC);
        out.setFrameBuffer(px.data(), 1, (size_t)width);
        out.writePixels(height);
    }, why, why_size);
}

extern "C" bool exr_layout_decode_rgba(const char *path, float *out, int width, int height,
                                       char *why, size_t why_size)
{
    return guarded([&] {
        Imf::RgbaInputFile in(path);
        std::vector<Imf::Rgba> px((size_t)width * (size_t)height);
        in.setFrameBuffer(px.data(), 1, (size_t)width);
        in.readPixels(0, height - 1);
        for (size_t i = 0; i < px.size(); i++) {
            out[4 * i] = px[i].r;
            out[4 * i + 1] = px[i].g;
            out[4 * i + 2] = px[i].b;
            out[4 * i + 3] = px[i].a;
        }
    }, why, why_size);
}
