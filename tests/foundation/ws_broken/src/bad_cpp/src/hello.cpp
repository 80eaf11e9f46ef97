#include <cstdio>

int main() {
  int x = 1
  std::printf("%d\n", x);
  return 0;
}
