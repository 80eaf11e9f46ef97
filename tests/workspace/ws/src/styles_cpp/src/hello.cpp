// Prints its arguments, then waits to be stopped (as a node would).
#include <csignal>
#include <cstdio>
#include <unistd.h>

static volatile std::sig_atomic_t stop = 0;

int main(int argc, char **argv) {
  std::signal(SIGINT, [](int) { stop = 1; });
  std::signal(SIGTERM, [](int) { stop = 1; });
  std::printf("hello from C++:");
  for (int i = 1; i < argc; ++i) std::printf(" %s", argv[i]);
  std::printf("\n");
  std::fflush(stdout);
  while (!stop) pause();
  return 0;
}
