/* One step of a generated module's node against the closed form of a chain of integrators.
 *
 * Each chain y^(r) = v is exact under zero-order hold: x1_i = sum_(l >= i) x0_l T^(l-i) / (l-i)!
 * + v T^(r-i) / (r-i)!. With P0 = I and q = 0 the prediction is P1 = A A', whose diagonal entry
 * i is sum_(l >= i) (T^(l-i) / (l-i)!)^2. After a dropped measurement (gamma = 0) the update
 * leaves the prior as it is, so node_predict must give exactly these up to rounding. Exit 0 when
 * every entry agrees, 1 otherwise; the model comes from -DPFX, -DUP and -DHEADER. */
#include <float.h>
#include <string.h>
#include HEADER

#define XC(a, b) a##_##b
#define C(a, b) XC(a, b)
#define F(n) C(PFX, n)
#define K(n) C(UP, n)
#define NX K(NX)
#define NY K(NY)

typedef F(real) real;

/* The sampling period of the closed form; a test overrides it to see the check fail. */
#ifndef CHECK_TS
#define CHECK_TS K(TS)
#endif

#if K(PRECISION_FLOAT)
#define EPS FLT_EPSILON
#else
#define EPS DBL_EPSILON
#endif

static real absval(real a)
{
    return a < 0 ? -a : a;
}

/* |got - want| within 64 roundings of the largest term: the kernel and this loop add the same
 * few terms in different orders, each rounding costs at most EPS / 2 of its size. */
static int close(real got, real want, real scale)
{
    return absval(got - want) <= (real)64 * EPS * scale;
}

int main(void)
{
    static F(node) node;
    const int degree[NY] = K(CHAIN_DEGREES);
    const int offset[NY] = K(CHAIN_OFFSETS);
    real x0[NX], P0[NX * NX], R[NY * NY], q[NY], v[NY], x[NX], P[NX * NX];
    int i, j, l, bad = 0;
    memset(P0, 0, sizeof(P0));
    memset(R, 0, sizeof(R));
    for (i = 0; i < NX; i++) {
        x0[i] = (real)(1 + i) / (real)(2 + 3 * i) * ((i % 2) ? -1 : 1);
        P0[i * NX + i] = 1;
    }
    for (j = 0; j < NY; j++) {
        R[j * NY + j] = 1;
        q[j] = 0;
        v[j] = (real)(j + 2) / 4;
    }
    if (F(node_init)(&node, x0, P0, R, q) != K(OK) || F(node_update)(&node, NULL, 0) != K(OK) ||
        F(node_predict)(&node, v) != K(OK) || F(node_estimate)(&node, x, P) != K(OK)) {
        return 1;
    }
    for (j = 0; j < NY; j++) {
        for (i = 0; i < degree[j]; i++) {
            real term = 1, want = 0, scale = 0, pii = 0;
            for (l = i; l < degree[j]; l++) {
                want += term * x0[offset[j] + l];
                scale += absval(term * x0[offset[j] + l]);
                pii += term * term;
                term = term * (real)(CHECK_TS) / (real)(l - i + 1);
            }
            want += term * v[j];
            scale += absval(term * v[j]);
            bad += !close(x[offset[j] + i], want, scale);
            bad += !close(P[(offset[j] + i) * NX + offset[j] + i], pii, pii);
        }
    }
    return bad ? 1 : 0;
}
