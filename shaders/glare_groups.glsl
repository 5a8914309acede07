// A still camera's glare from the history's light groups (render/pass_glare.cpp): the glare is
// linear in the frame's light, which is the groups' sum with their factors since the history
// (temporal.frag, STRIDE 0), so it is the sum of each group's glare with the same factors. The
// result is what glare_up.frag's finest level holds: keep x the march + the spread light, the
// march's transmittance. `factors`: the flash's and the channel's since the history.
vec4 glare_from_groups(vec4 march, vec3 flash, vec3 statics, vec3 channel, vec2 factors, float keep) {
    vec3 spread = factors.x * flash + statics + factors.y * channel;
    return vec4(keep * march.rgb + spread, march.a);
}
