// Interpolation of S between the baked output directions (mirror of direction_weights() in
// engine/render/directions.cpp; the tie-breaking must stay identical).
//
// The direction d is projected onto the unit cube (gnomonic: d / max|d_i|). Each cube face
// is a 2x2 grid of cells whose nodes are the 26 lattice directions (face centre, edge
// midpoints, corners). Inside a cell the weights are bilinear in smoothstep-remapped cell
// coordinates: non-negative, summing to 1, exactly 1 at a node, and C1 across cell and face
// boundaries (smoothstep has zero slope at 0 and 1). Smaller baked sets fold missing lattice
// directions onto present ones (u_fold_* tables built by detail::fold_table()).

// The four lattice nodes of the cube-face cell containing unit d (as lattice codes
// (x+1) + 3(y+1) + 9(z+1)) and their weights. Written without dynamic vector indexing, which
// software rasterizers execute slowly: the components are permuted so that p.x is the major
// axis a, p.y axis (a+1) mod 3 and p.z axis (a+2) mod 3.
void cube_cell_weights(vec3 d, out ivec4 code, out vec4 w) {
    vec3 ad = abs(d);
    vec3 p;
    ivec3 mul;  // code multiplier of each permuted component
    if (ad.x >= ad.y && ad.x >= ad.z) {
        p = d.xyz;
        mul = ivec3(1, 3, 9);
    } else if (ad.y >= ad.z) {
        p = d.yzx;
        mul = ivec3(3, 9, 1);
    } else {
        p = d.zxy;
        mul = ivec3(9, 1, 3);
    }
    float u = p.y / abs(p.x), v = p.z / abs(p.x);
    int sa = p.x >= 0.0 ? 1 : -1, su = u >= 0.0 ? 1 : -1, sv = v >= 0.0 ? 1 : -1;
    float fu = smoothstep(0.0, 1.0, min(abs(u), 1.0)), fv = smoothstep(0.0, 1.0, min(abs(v), 1.0));
    int c00 = 13 + sa * mul.x;
    code = ivec4(c00, c00 + su * mul.y, c00 + sv * mul.z, c00 + su * mul.y + sv * mul.z);
    w = vec4((1.0 - fu) * (1.0 - fv), fu * (1.0 - fv), (1.0 - fu) * fv, fu * fv);
}
