// Interpolation of S between the baked output directions (mirror of direction_weights() in
// engine/render/directions.cpp; the tie-breaking must stay identical).
//
// The direction d is projected onto the unit cube (gnomonic: d / max|d_i|). Each cube face
// is a 2x2 grid of cells whose nodes are the 26 lattice directions (face centre, edge
// midpoints, corners). Inside a cell the weights are bilinear in smoothstep-remapped cell
// coordinates: non-negative, summing to 1, exactly 1 at a node, and C1 across cell and face
// boundaries (smoothstep has zero slope at 0 and 1). Smaller baked sets fold missing lattice
// directions onto present ones (u_fold_* tables built by detail::fold_table()).

// Lattice code of a vector with components in {-1, 0, 1}.
int lattice_code(ivec3 l) { return (l.x + 1) + 3 * (l.y + 1) + 9 * (l.z + 1); }

// The four lattice nodes of the cell containing unit d, and their weights.
void cube_cell_weights(vec3 d, out ivec4 code, out vec4 w) {
    vec3 ad = abs(d);
    int a = (ad.x >= ad.y && ad.x >= ad.z) ? 0 : (ad.y >= ad.z ? 1 : 2);
    int b = (a + 1) % 3, c = (a + 2) % 3;
    float u = d[b] / ad[a], v = d[c] / ad[a];
    int sa = d[a] >= 0.0 ? 1 : -1, su = u >= 0.0 ? 1 : -1, sv = v >= 0.0 ? 1 : -1;
    float fu = smoothstep(0.0, 1.0, min(abs(u), 1.0)), fv = smoothstep(0.0, 1.0, min(abs(v), 1.0));
    ivec3 l00 = ivec3(0);
    l00[a] = sa;
    ivec3 l10 = l00, l01 = l00, l11 = l00;
    l10[b] = su;
    l01[c] = sv;
    l11[b] = su;
    l11[c] = sv;
    code = ivec4(lattice_code(l00), lattice_code(l10), lattice_code(l01), lattice_code(l11));
    w = vec4((1.0 - fu) * (1.0 - fv), fu * (1.0 - fv), (1.0 - fu) * fv, fu * fv);
}
