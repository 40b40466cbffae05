// Between the visibility and the accumulation pass: the visibility record (visibility.glsl) with the
// pixels that no disk covers but 3 or 4 of whose 4 neighbours are covered marked SIDE_CRACK: a crack
// that straight clip lines leave between disks, which the filters' fringes fill (fringe_hidden in
// splat_fragment.glsl). Done once per pixel here, the accumulation pass reads one texel per fragment
// instead of five: llvmpipe fetches the texels of a branch for every fragment, taken or not (measured
// on the bunny, 1M splats at 1024x1024: the four neighbour fetches were a quarter of that pass).
#include "camera.glsl"
#include "visibility.glsl"

layout(location = 0) out vec2 out_side;

void main() {
    vec2 record = texelFetch(u_side, ivec2(gl_FragCoord.xy), 0).rg;
    if (!covered_side(record.x)) {
        int covered = int(disk_at(ivec2(1, 0))) + int(disk_at(ivec2(-1, 0))) + int(disk_at(ivec2(0, 1)))
                      + int(disk_at(ivec2(0, -1)));
        record.x = covered >= 3 ? SIDE_CRACK : SIDE_NONE;
    }
    out_side = record;
}
