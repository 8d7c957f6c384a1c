/* Deterministic RNG: xoshiro256** (Blackman & Vigna) seeded by splitmix64
 * from (seed, stream). Normal draws use Box-Muller without a cached second
 * value, so a draw sequence depends only on the state. */
#include "sooc3d/core.h"

#include <math.h>

static uint64_t splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

void sooc_rng_seed(sooc_rng *r, uint64_t seed, uint64_t stream) {
    uint64_t x = seed ^ (stream * 0xd1342543de82ef95ULL + 0x632be59bd9b4e019ULL);
    /* Mix the stream a second time so that (seed, stream) pairs that collide
     * in the xor above still differ. */
    uint64_t y = splitmix64(&x) ^ stream;
    for (int i = 0; i < 4; i++) r->s[i] = splitmix64(&y);
    if (!(r->s[0] | r->s[1] | r->s[2] | r->s[3])) r->s[0] = 1;
}

static inline uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

uint64_t sooc_rng_u64(sooc_rng *r) {
    uint64_t *s = r->s;
    uint64_t res = rotl(s[1] * 5, 7) * 9;
    uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return res;
}

uint32_t sooc_rng_u32(sooc_rng *r) { return (uint32_t)(sooc_rng_u64(r) >> 32); }
double sooc_rng_uniform(sooc_rng *r) { return (double)(sooc_rng_u64(r) >> 11) * 0x1.0p-53; }
float sooc_rng_uniformf(sooc_rng *r) { return (float)(sooc_rng_u64(r) >> 40) * 0x1.0p-24f; }
double sooc_rng_uniform_open(sooc_rng *r) {
    return ((double)(sooc_rng_u64(r) >> 11) + 0.5) * 0x1.0p-53;
}
double sooc_rng_range(sooc_rng *r, double lo, double hi) { return lo + (hi - lo) * sooc_rng_uniform(r); }

uint32_t sooc_rng_below(sooc_rng *r, uint32_t n) {
    if (n <= 1) return 0;
    /* Lemire's nearly-divisionless method with rejection. */
    uint64_t m = (uint64_t)sooc_rng_u32(r) * n;
    uint32_t l = (uint32_t)m;
    if (l < n) {
        uint32_t t = (uint32_t)(-n) % n;
        while (l < t) {
            m = (uint64_t)sooc_rng_u32(r) * n;
            l = (uint32_t)m;
        }
    }
    return (uint32_t)(m >> 32);
}

double sooc_rng_normal(sooc_rng *r) {
    double u1 = sooc_rng_uniform_open(r), u2 = sooc_rng_uniform(r);
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

double sooc_rng_logistic(sooc_rng *r) {
    double u = sooc_rng_uniform_open(r);
    return log(u) - log1p(-u);
}
