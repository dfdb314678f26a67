#include <cstdio>
int main() { std::puts("lambert (skeleton)"); return 0; }
