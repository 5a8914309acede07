// Internal to fulgur::render: the automatic exposure chosen from a luminance histogram (the
// meter pass reads back the ray march's histogram; tests call this directly).
#pragma once

#include "render/render.h"

#include <cstdint>
#include <span>

namespace fulgur::render::detail {

/// Exposed luminance the automatic exposure puts the frame's highlights at: the ACES fit
/// shows it at 0.87 linear (~240 of 255), below the soft shoulder's end.
inline constexpr double kHighlightExposed = 3.0;
/// Exposed luminance the tone curve shows at the display's white for a neutral colour
/// (0.996 linear, 8-bit 255, is reached at ~20.7; a bluish flash clips its blue channel first).
inline constexpr double kWhiteExposed = 16.0;

struct ExposureChoice {
    double metered = 0.0;      ///< what the frame calls for (compensation included)
    double applied = 0.0;      ///< after adaptation from Settings::previous_exposure
    double log_average = 0.0;  ///< log-average luminance of the non-black pixels (W m^-2 sr^-1)
};

/// bins[b] counts pixels of luminance in [2^(log2_min + b w), 2^(log2_min + (b+1) w)), bin 0
/// also black pixels. The exposure is the lower of
///   * the key: the log-average luminance L_lit of the lit pixels (those at or above the
///     log-average of the non-black ones) mapped to the Krawczyk, Myszkowski & Seidel 2005
///     key of its luminance in cd/m^2 (taken as 683 L_lit), so dim scenes stay dim and bright
///     ones bright;
///   * the highlights: the luminance exceeded by settings.highlight_fraction of the lit pixels
///     (a bin's pixels taken as spread evenly in log luminance over it: continuous in the
///     counts) mapped to kHighlightExposed, below the tone curve's white;
/// then the compensation and the adaptation. A frame with no non-black pixel keeps
/// settings.previous_exposure (else settings.exposure).
ExposureChoice choose_exposure(std::span<const std::uint32_t> bins, double log2_min, double bin_width,
                               const Settings& settings);

}  // namespace fulgur::render::detail
