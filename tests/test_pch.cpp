// The program that owns the test programs' precompiled headers (tests/CMakeLists.txt): it is
// built first, and every GoogleTest program reuses its header image. It runs no test.
int main() { return 0; }
