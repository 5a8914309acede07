#version 450 core
// The stars of a moving camera's frame as points: one vertex per cell of the stars' cube map
// that may hold a star (u_cells, listed by render/pass_composite.cpp: ~7% of the 6 kStarCells^2
// cells, numbered face, row, column). A cell holding a star becomes a point covering every
// output pixel its spot reaches (r < kStarSpot in stars()); the others are dropped. The
// fragment shader is the composite's with its stars (composite.frag, STARS 1), drawn over the
// composite without them, so those pixels get what the composite with stars gives, and no
// other pixel has a star. The viewport has a guard band of u_guard pixels on each side: a
// point whose centre lies off the frame still reaches into it.
#include "common.glsl"
#include "background.glsl"

uniform float u_guard;  // pixels
layout(std430, binding = 5) readonly buffer Cells { uint u_cells[]; };

// The output pixel a direction p (need not be unit) projects to; false behind the camera.
bool to_pixel(vec3 p, out vec2 pixel) {
    float z = dot(p, cam_fwd.xyz);
    pixel = vec2(0.0);
    if (z <= 0.0) return false;
    vec2 ndc = vec2(dot(p, cam_right.xyz) / (z * cam_pos.w * cam_fwd.w), dot(p, cam_up.xyz) / (z * cam_pos.w)) -
               vec2(cam_right.w, cam_up.w);
    pixel = (ndc * 0.5 + 0.5) * sizes.xy;
    return true;
}

void main() {
    const int edge = int(kStarCells), per_face = edge * edge;
    int id = int(u_cells[gl_VertexID]);
    uint face = uint(id / per_face);
    int i = id % per_face;
    vec2 cell = vec2(i % edge, i / edge);
    vec4 u = star_draws(cell, face);
    gl_PointSize = 1.0;
    gl_Position = vec4(2.0, 2.0, 0.0, 1.0);  // outside the view: dropped
    vec2 star = star_position(cell, u), centre;
    vec3 ps = cube_face_direction(face, star);
    if (u.x >= kStarProbability || !to_pixel(ps, centre)) return;
    // The spot: r < kStarSpot where |uv - star| < kStarSpot pixel_angle (1 + |uv|^2), uv on this
    // face (|uv|^2 <= 2): a disc of face coordinates of radius `reach` around the star. Over a
    // few pixels the projection onto the screen is affine to ~1e-3 of the spot's size, so the
    // disc projects into an ellipse whose box has the half-widths |(a.x, b.x)| and |(a.y, b.y)|,
    // a and b the images of the disc's two radii along the face's axes (a pixel more below
    // covers the rest and the pixels' centres).
    float pixel_angle = 2.0 * cam_pos.w / sizes.y;
    float near = kStarSpot * pixel_angle;
    float far = min(length(star) + 3.0 * near, sqrt(2.0));
    float reach = near * (1.0 + far * far);
    vec2 a, b;
    vec3 pa = cube_face_direction(face, star + vec2(reach, 0.0)), pb = cube_face_direction(face, star + vec2(0.0, reach));
    // An end behind the camera with the star in front: the star lies a few pixel angles from 90
    // degrees off the view axis, outside any frame the composite draws points for.
    if (!to_pixel(pa, a) || !to_pixel(pb, b)) return;
    // The whole spot below the horizon (z is linear in uv: its largest value on the disc is at
    // most this): star_radiance() is 0 there.
    if (ps.z + abs(pa.z - ps.z) + abs(pb.z - ps.z) <= 0.0) return;
    a -= centre;
    b -= centre;
    float half_size = max(length(vec2(a.x, b.x)), length(vec2(a.y, b.y)));
    gl_PointSize = 2.0 * (half_size + 1.0);
    gl_Position = vec4((centre + u_guard) / (sizes.xy + 2.0 * u_guard) * 2.0 - 1.0, 0.0, 1.0);
}
