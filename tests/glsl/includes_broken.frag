// Includes broken_lib.glsl on line 3, after a package file (tests/test_shaders.py).
#include "camera.glsl"
#include "broken_lib.glsl"
out vec4 out_color;

void main() {
    out_color = vec4(broken_helper(1.0));
}
