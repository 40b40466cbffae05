// An included file whose line 4 names an undeclared variable (tests/test_shaders.py).
float broken_helper(float x) {
    float y = x * 2.0;
    return y + undefined_in_lib;
}
