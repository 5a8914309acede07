// The meter pass (automatic exposure): a log2 luminance histogram of the march, read back,
// and the exposure chosen from it written into the frame block.
#include "render/detail/exposure.h"
#include "render/detail/renderer_impl.h"

#include <glad/gl.h>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace fulgur::render {

using detail::FrameBlock;
using detail::FrameUniforms;
using detail::kMeter;
using detail::PassTimer;

namespace {

// Exposure metering: log2 bins of the march's luminance over float32's whole normal range,
// 2^-126 to 2^130, a quarter stop each: any light a scene may declare (a night sky at 1e-9, a
// sun of 1e30 W/m^2) is metered where it is, never pinned at an end of the range.
constexpr int kMeterBins = 1024;
constexpr float kMeterLog2Min = -126.0f, kMeterBinWidth = 0.25f;

}  // namespace

/// Meter (automatic exposure): a log2 luminance histogram of the march, read back; the chosen
/// exposure replaces the frame's (the composite reads it from the frame block).
void Renderer::Impl::meter_pass(const Settings& st, const FrameUniforms& u, PassTimer& timer, FrameStats& stats) {
    stats.exposure = st.exposure;
    if (!st.auto_exposure) return;
    // The history's march unchanged since the meter counted it (a still frame between flashes):
    // the same histogram. The exposure is chosen again (its adaptation moves with the frame). A
    // frame rendered without the history between two with it leaves the history's histogram kept.
    const std::uint64_t version = march_out == &temporal.march ? temporal.march_version : 0;
    const int stride = st.meter_stride;
    const bool kept = version != 0 && version == meter_version && stride == meter_stride;
    std::vector<std::uint32_t> counted;
    if (!kept) {
        timer.begin(kMeter);
        const GLuint p = program("meter", {{GL_COMPUTE_SHADER, "meter.comp"}});
        glUseProgram(p);
        const std::vector<std::uint32_t> zero(kMeterBins, 0u);
        meter_buf.upload(zero.data(), zero.size() * sizeof(std::uint32_t));
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, meter_buf.id);
        glBindTextureUnit(3, march_out->tex);
        glUniform1i(glGetUniformLocation(p, "u_bins"), kMeterBins);
        glUniform1f(glGetUniformLocation(p, "u_log2_min"), kMeterLog2Min);
        glUniform1f(glGetUniformLocation(p, "u_bin_width"), kMeterBinWidth);
        glUniform1i(glGetUniformLocation(p, "u_stride"), stride);
        glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
        // 32x32 tiles of the counted pixels, one of each stride x stride block.
        const int counted_w = (u.internal_width + stride - 1) / stride;
        const int counted_h = (u.internal_height + stride - 1) / stride;
        glDispatchCompute(GLuint((counted_w + 31) / 32), GLuint((counted_h + 31) / 32), 1);
        glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
        counted.resize(kMeterBins);
        glGetNamedBufferSubData(meter_buf.id, 0, GLsizeiptr(counted.size() * sizeof(std::uint32_t)), counted.data());
        if (version != 0) {
            meter_bins = counted;
            meter_version = version;
            meter_stride = stride;
        }
        timer.end(kMeter);
    }
    const detail::ExposureChoice c =
        detail::choose_exposure(kept ? meter_bins : counted, kMeterLog2Min, kMeterBinWidth, st);
    stats.metered_exposure = c.metered;
    stats.exposure = c.applied;
    const float e = float(c.applied);
    glNamedBufferSubData(frame_ubo, GLintptr(offsetof(FrameBlock, sky_params) + 3 * sizeof(float)), sizeof(float), &e);
}

}  // namespace fulgur::render
