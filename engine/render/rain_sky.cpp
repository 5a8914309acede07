// The table of the rain's sky light the march interpolates (render::rain_sky_shares).
#include "render/render.h"
#include "transport/transport.h"

namespace fulgur::render {

std::array<float, 65> rain_sky_shares(double g) {
    std::array<float, 65> s{};
    for (std::size_t k = 0; k < s.size(); ++k) {
        const double mu = -1.0 + double(k) / 32.0;
        s[k] = float(transport::hg_from_above(mu, g) - transport::hg_from_above(mu, g, 1));
    }
    return s;
}

}  // namespace fulgur::render
