// The sun's course over a day (sky.h, SunCourse): the time-of-day control's sun.
#include "sky/sky.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace fulgur::sky {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
// Vertical optical depth of a clear atmosphere at 650, 550 and 450 nm: Rayleigh (0.05, 0.10,
// 0.22, as lambda^-4) + 0.05 of aerosol: a low sun turns orange, as the dusk scene's.
constexpr double kTau[3] = {0.10, 0.15, 0.27};
// Lowest elevation the course reaches (degrees): below it the air mass diverges and a sun
// lighting the cloud from below the ground makes no sense.
constexpr double kLowest = 1.0;

// Relative air mass at elevation el (degrees): Kasten & Young 1989.
double air_mass(double el_deg) {
    return 1.0 / (std::sin(el_deg * kDeg) + 0.50572 * std::pow(el_deg + 6.07995, -1.6364));
}

glm::dvec3 transmittance(double el_deg) {
    const double m = air_mass(el_deg);
    return {std::exp(-kTau[0] * m), std::exp(-kTau[1] * m), std::exp(-kTau[2] * m)};
}

}  // namespace

SunCourse sun_course(const scene::Sun& sun) {
    SunCourse c;
    c.scene_sun = sun;
    scene::sun_angles(sun.direction, c.scene_elevation, c.scene_azimuth);
    FULGUR_ASSERT(c.scene_elevation > 0.0, "the scene's sun is above the horizon (scene parsing checks it)");
    // An equinox day (declination 0) at a latitude whose noon sun stands at least 10 degrees
    // above the scene's (and at least 50): the course always passes through the scene's sun.
    const double noon = std::clamp(std::max(50.0, c.scene_elevation + 10.0), 50.0, 89.0);
    c.latitude = 90.0 - noon;
    const double cos_lat = std::cos(c.latitude * kDeg);
    // Elevation el at hour angle H: sin el = cos(lat) cos H. The scene's sun in the afternoon.
    const double h0 = std::acos(std::min(1.0, std::sin(c.scene_elevation * kDeg) / cos_lat)) / kDeg;
    c.scene_hour = 12.0 + h0 / 15.0;
    const double h_max = std::acos(std::sin(kLowest * kDeg) / cos_lat) / kDeg;
    c.first_hour = 12.0 - h_max / 15.0;
    c.last_hour = 12.0 + h_max / 15.0;
    // The course's azimuth turned so that it passes through the scene's.
    c.azimuth_offset = 0.0;
    double el0 = 0.0, az0 = 0.0;
    c.angles(c.scene_hour, el0, az0);
    c.azimuth_offset = c.scene_azimuth - az0;
    return c;
}

void SunCourse::angles(double hour, double& elevation_deg, double& azimuth_deg) const {
    const double H = 15.0 * (hour - 12.0) * kDeg, lat = latitude * kDeg;
    // Toward the sun in a local frame (x east, y north, z up), declination 0.
    const glm::dvec3 to_sun{-std::sin(H), -std::sin(lat) * std::cos(H), std::cos(lat) * std::cos(H)};
    elevation_deg = std::asin(std::clamp(to_sun.z, -1.0, 1.0)) / kDeg;
    azimuth_deg = std::atan2(to_sun.y, to_sun.x) / kDeg + azimuth_offset;
}

scene::Sun SunCourse::at(double hour) const {
    hour = std::clamp(hour, first_hour, last_hour);
    double el = 0.0, az = 0.0;
    angles(hour, el, az);
    scene::Sun s = scene_sun;
    s.direction = scene::sun_direction(el, az);
    // The scene's colour and irradiance are its sun's at its elevation: another elevation
    // sees them through another air mass.
    const glm::dvec3 c = scene_sun.colour * transmittance(el) / transmittance(scene_elevation);
    const double lum = scene::luminance(c);
    s.colour = c / lum;
    s.irradiance = scene_sun.irradiance * lum;
    return s;
}

}  // namespace fulgur::sky
