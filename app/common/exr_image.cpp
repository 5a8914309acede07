#include "exr_image.h"

#include "core/core.h"
#include "core/files.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfVecAttribute.h>

#include <algorithm>
#include <exception>

namespace fulgur::app {

namespace {

// OpenEXR's output stream over an AtomicFile: the scan-line offset table is written last, by
// seeking back.
class AtomicStream : public Imf::OStream {
public:
    explicit AtomicStream(core::AtomicFile& file) : Imf::OStream(file.target().c_str()), file_(file) {}
    void write(const char c[], int n) override {
        file_.write(c, std::size_t(n));
        pos_ += std::uint64_t(n);
    }
    std::uint64_t tellp() override { return pos_; }
    void seekp(std::uint64_t pos) override {
        file_.seek(pos);
        pos_ = pos;
    }

private:
    core::AtomicFile& file_;
    std::uint64_t pos_ = 0;
};

std::string full_name(const ExrLayer& l, const std::string& channel) {
    return l.name.empty() ? channel : l.name + "." + channel;
}

Imath::M44f to_imath(const glm::dmat4& m) {
    Imath::M44f r;  // the same memory order: glm's column c is Imath's row c (Imath multiplies row vectors)
    for (int c = 0; c < 4; ++c)
        for (int k = 0; k < 4; ++k) r.x[c][k] = float(m[c][k]);
    return r;
}

}  // namespace

void write_exr(const std::filesystem::path& path, int width, int height, std::span<const ExrLayer> layers,
               const ExrHeader& header) {
    const std::string where = path.string();
    FULGUR_ASSERT(width > 0 && height > 0, "an EXR needs pixels");
    const std::size_t pixels = std::size_t(width) * std::size_t(height);
    for (const ExrLayer& l : layers) {
        FULGUR_ASSERT(!l.channels.empty() && l.values.size() == pixels * l.channels.size(),
                      "one value per pixel and channel");
        core::check_finite(l.values, where, l.name.empty() ? "radiance" : l.name);
    }
    Imf::Header h(width, height);
    h.compression() = Imf::ZIP_COMPRESSION;
    for (const auto& [k, v] : header.text) h.insert(k, Imf::StringAttribute(v));
    for (const auto& [k, v] : header.numbers) h.insert(k, Imf::DoubleAttribute(v));
    for (const auto& [k, v] : header.vectors) h.insert(k, Imf::V3dAttribute(Imath::V3d(v.x, v.y, v.z)));
    if (header.world_to_camera) Imf::addWorldToCamera(h, to_imath(*header.world_to_camera));
    if (header.world_to_ndc) Imf::addWorldToNDC(h, to_imath(*header.world_to_ndc));
    Imf::FrameBuffer fb;
    for (const ExrLayer& l : layers) {
        const std::size_t nc = l.channels.size();
        for (std::size_t c = 0; c < nc; ++c) {
            const std::string name = full_name(l, l.channels[c]);
            h.channels().insert(name, Imf::Channel(Imf::FLOAT));
            // const_cast: OpenEXR's Slice takes char*, and the writer only reads it.
            fb.insert(name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(l.values.data() + c)),
                                       sizeof(float) * nc, sizeof(float) * nc * std::size_t(width)));
        }
    }
    core::AtomicFile file(path);
    try {
        AtomicStream stream(file);
        Imf::OutputFile out(stream, h, 1);
        out.setFrameBuffer(fb);
        out.writePixels(height);
    } catch (const core::Error&) {
        throw;
    } catch (const std::exception& e) {
        throw core::Error(where, std::string("writing the EXR failed: ") + e.what());
    }
    file.commit();
}

ExrImage read_exr(const std::filesystem::path& path, std::uint64_t max_pixels) {
    const std::string where = path.string();
    core::check_readable_file(path, std::uint64_t(4) << 30, "EXR");
    ExrImage img;
    try {
        Imf::InputFile in(path.c_str(), 1);
        const Imath::Box2i dw = in.header().dataWindow();
        const std::int64_t w = std::int64_t(dw.max.x) - dw.min.x + 1, hgt = std::int64_t(dw.max.y) - dw.min.y + 1;
        if (w <= 0 || hgt <= 0 || std::uint64_t(w) * std::uint64_t(hgt) > max_pixels)
            throw core::Error(where, "data window of " + std::to_string(w) + " x " + std::to_string(hgt) +
                                         " pixels is empty or larger than " + std::to_string(max_pixels));
        img.width = int(w);
        img.height = int(hgt);
        const std::size_t pixels = std::size_t(w) * std::size_t(hgt);
        Imf::FrameBuffer fb;
        std::size_t count = 0;
        for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it) {
            if (++count > 64) throw core::Error(where, "more than 64 channels");
            if (it.channel().type == Imf::UINT)
                throw core::Error(where, std::string("channel ") + it.name() + " holds integers, not radiance");
            if (it.channel().xSampling != 1 || it.channel().ySampling != 1)
                throw core::Error(where, std::string("channel ") + it.name() + " is subsampled");
            std::vector<float>& v = img.channels[it.name()];
            v.assign(pixels, 0.0f);
            char* base = reinterpret_cast<char*>(v.data()) -
                         (std::ptrdiff_t(dw.min.x) + std::ptrdiff_t(dw.min.y) * std::ptrdiff_t(w)) *
                             std::ptrdiff_t(sizeof(float));
            fb.insert(it.name(), Imf::Slice(Imf::FLOAT, base, sizeof(float), sizeof(float) * std::size_t(w)));
        }
        in.setFrameBuffer(fb);
        in.readPixels(dw.min.y, dw.max.y);
        for (auto it = in.header().begin(); it != in.header().end(); ++it) {
            if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute()))
                img.text[it.name()] = s->value();
            else if (const auto* d = dynamic_cast<const Imf::DoubleAttribute*>(&it.attribute()))
                img.numbers[it.name()] = d->value();
            else if (const auto* v3 = dynamic_cast<const Imf::V3dAttribute*>(&it.attribute()))
                img.vectors[it.name()] = glm::dvec3(v3->value().x, v3->value().y, v3->value().z);
        }
    } catch (const core::Error&) {
        throw;
    } catch (const std::exception& e) {
        throw core::Error(where, std::string("not a readable EXR: ") + e.what());
    }
    return img;
}

}  // namespace fulgur::app
