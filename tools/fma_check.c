/* Spec §3.6 step 3 under a C compiler that fuses multiplies and adds (-ffp-contract=fast,
 * GCC's default outside ISO mode, with -march=native enabling FMA): evaluated in binary64 as
 * the spec says, the rotation's largest component comes out the same whether the products
 * are fused or not; evaluated in binary32 it does not. Triples (a, b, c) near the unit
 * sphere, where binary32 loses m. Build and run: tools/fma_check.sh */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

/* As written in the spec; the compiler may contract it. */
static float m_spec(float a, float b, float c) {
  double x = a, y = b, z = c;
  double t = 1.0 - ((x * x + y * y) + z * z);
  return t > 0.0 ? (float)sqrt(t) : 0.0f;
}

/* Every product fused, explicitly. */
static float m_fused(float a, float b, float c) {
  double x = a, y = b, z = c;
  double t = 1.0 - fma(z, z, fma(x, x, y * y));
  return t > 0.0 ? (float)sqrt(t) : 0.0f;
}

/* The old binary32 form, unfused and fused. */
static float m32(float a, float b, float c) {
  volatile float aa = a * a, bb = b * b, cc = c * c;
  float t = 1.0f - ((aa + bb) + cc);
  return t > 0.0f ? sqrtf(t) : 0.0f;
}
static float m32_fused(float a, float b, float c) {
  float t = 1.0f - fmaf(c, c, fmaf(a, a, b * b));
  return t > 0.0f ? sqrtf(t) : 0.0f;
}

static uint32_t bits(float f) { uint32_t u; memcpy(&u, &f, 4); return u; }

int main(void) {
  uint64_t s = 0x9e3779b97f4a7c15u;
  long n = 0, differ64 = 0, differ32 = 0;
  const double tol = 1.0 / 16384;
  for (long i = 0; i < 1000000; i++) {
    s ^= s << 13; s ^= s >> 7; s ^= s << 17;
    /* A direction on the sphere, nudged by a few binary32 units. */
    double u = (double)(s >> 11) / 9007199254740992.0 * 6.283185307179586;
    double v = (double)((s >> 3) & 0xffffff) / 16777216.0 * 1.5707963267948966;
    float a = (float)(cos(u) * sin(v)), b = (float)(sin(u) * sin(v)), c = (float)cos(v);
    if (i == 0) { a = 0.577296913f; b = 0.577369153f; c = 0.57738471f; }
    n++;
    if (bits(m_spec(a, b, c)) != bits(m_fused(a, b, c))) differ64++;
    if (fabs((double)m32(a, b, c) - (double)m32_fused(a, b, c)) > tol * (1 + fabs(m32(a, b, c))))
      differ32++;
  }
  printf("binary64 (spec): %ld of %ld triples differ fused against unfused; binary32: %ld beyond "
         "the 2^-14 tolerance\n", differ64, n, differ32);
  return differ64 == 0 && differ32 > 0 ? 0 : 1;
}
