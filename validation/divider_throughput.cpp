// How often this core issues a 4-lane double square root and division (eight independent
// chains, so that the divider's throughput and not its latency is timed). The figures behind "what
// sets the limit" in validation/results/speed_user_flows.md.
// usage: g++ -O2 -march=native validation/divider_throughput.cpp -o /tmp/divider && /tmp/divider
#include <immintrin.h>

#include <chrono>
#include <cstdio>

template <int Kind>
void time_kind(const char* name) {
  const long n = 50000000;
  __m256d a[8];
  for (int k = 0; k < 8; ++k) a[k] = _mm256_set1_pd(1.1 + 0.1 * k);
  const __m256d b = _mm256_set1_pd(1.0000001);
  const auto start = std::chrono::steady_clock::now();
  for (long i = 0; i < n; ++i)
    for (auto& x : a)
      x = Kind == 0   ? _mm256_sqrt_pd(x)
          : Kind == 1 ? _mm256_div_pd(x, b)
                      : _mm256_fmadd_pd(x, b, b);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  double sum = 0;  // the results are used, so the loop is not removed
  for (const auto& x : a) sum += x[0];
  std::printf("%-8s %.2f ns per 4-lane instruction (%g)\n", name, 1e9 * s / (8.0 * n), sum);
}

int main() {
  time_kind<0>("vsqrtpd");
  time_kind<1>("vdivpd");
}
