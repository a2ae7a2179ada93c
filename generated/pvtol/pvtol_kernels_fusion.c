/* DO NOT EDIT: pvtol module, generated from template kernels.c.j2 by dfeif-codegen 0.1.0;
 * regenerate with `codegen build pvtol`. */
/* Master fusion kernels: master_gain, fuse_finish. Printed as C loops (over static parts, if
 * any): master_gain, fuse_finish.
 * Straight-line code printed by CasADi 3.8 and post-processed by
 * dfeif_codegen.kernels (helpers static, named entry points, double arithmetic only); a
 * kernel that is another on packed copies of its matrices is that call between two copy loops. */
#include <math.h>
#include "pvtol_internal.h"

/* pvtol_kern_master_gain:(x[8],P[8x8],xp[8],Pp[8x8],c[8])->(dY[36],dy[8],piv[16]) */
int pvtol_kern_master_gain(const pvtol_real x[8], const pvtol_real P[64], const pvtol_real xp[8],
                           const pvtol_real Pp[64], const pvtol_real c[8], pvtol_real dY[36],
                           pvtol_real dy[8], pvtol_real piv[16])
{
    pvtol_real L[64]; /* the Cholesky factor by rows, then its inverse's columns */
    pvtol_real Yf[64];
    pvtol_real s;
    int i;
    int j;
    int k;
    pvtol_real e[8];
    pvtol_real z[8];
    for (i = 0; i < 8; i++) {
        s = P[i];
        if (i == 0) {
            piv[0] = s;
            L[0] = sqrt(s);
        } else {
            L[(i * 8)] = s / L[0];
        }
    }
    for (i = 1; i < 8; i++) {
        s = P[i + 8];
        s = s - (L[(i * 8)] * L[8]);
        if (i == 1) {
            piv[1] = s;
            L[9] = sqrt(s);
        } else {
            L[(i * 8) + 1] = s / L[9];
        }
    }
    for (i = 2; i < 8; i++) {
        s = P[i + 16];
        s = s - (L[(i * 8)] * L[16]);
        s = s - (L[(i * 8) + 1] * L[17]);
        if (i == 2) {
            piv[2] = s;
            L[18] = sqrt(s);
        } else {
            L[(i * 8) + 2] = s / L[18];
        }
    }
    for (i = 3; i < 8; i++) {
        s = P[i + 24];
        s = s - (L[(i * 8)] * L[24]);
        s = s - (L[(i * 8) + 1] * L[25]);
        s = s - (L[(i * 8) + 2] * L[26]);
        if (i == 3) {
            piv[3] = s;
            L[27] = sqrt(s);
        } else {
            L[(i * 8) + 3] = s / L[27];
        }
    }
    for (i = 4; i < 8; i++) {
        s = P[i + 32];
        s = s - (L[(i * 8)] * L[32]);
        s = s - (L[(i * 8) + 1] * L[33]);
        s = s - (L[(i * 8) + 2] * L[34]);
        s = s - (L[(i * 8) + 3] * L[35]);
        if (i == 4) {
            piv[4] = s;
            L[36] = sqrt(s);
        } else {
            L[(i * 8) + 4] = s / L[36];
        }
    }
    for (i = 5; i < 8; i++) {
        s = P[i + 40];
        s = s - (L[(i * 8)] * L[40]);
        s = s - (L[(i * 8) + 1] * L[41]);
        s = s - (L[(i * 8) + 2] * L[42]);
        s = s - (L[(i * 8) + 3] * L[43]);
        s = s - (L[(i * 8) + 4] * L[44]);
        if (i == 5) {
            piv[5] = s;
            L[45] = sqrt(s);
        } else {
            L[(i * 8) + 5] = s / L[45];
        }
    }
    for (i = 6; i < 8; i++) {
        s = P[i + 48];
        s = s - (L[(i * 8)] * L[48]);
        s = s - (L[(i * 8) + 1] * L[49]);
        s = s - (L[(i * 8) + 2] * L[50]);
        s = s - (L[(i * 8) + 3] * L[51]);
        s = s - (L[(i * 8) + 4] * L[52]);
        s = s - (L[(i * 8) + 5] * L[53]);
        if (i == 6) {
            piv[6] = s;
            L[54] = sqrt(s);
        } else {
            L[(i * 8) + 6] = s / L[54];
        }
    }
    for (i = 7; i < 8; i++) {
        s = P[i + 56];
        s = s - (L[(i * 8)] * L[56]);
        s = s - (L[(i * 8) + 1] * L[57]);
        s = s - (L[(i * 8) + 2] * L[58]);
        s = s - (L[(i * 8) + 3] * L[59]);
        s = s - (L[(i * 8) + 4] * L[60]);
        s = s - (L[(i * 8) + 5] * L[61]);
        s = s - (L[(i * 8) + 6] * L[62]);
        if (i == 7) {
            piv[7] = s;
            L[63] = sqrt(s);
        } else {
            L[(i * 8) + 7] = s / L[63];
        }
    }
    for (j = 0; j < 7; j++) {
        i = j + 1;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 6; j++) {
        i = j + 2;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 5; j++) {
        i = j + 3;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 4; j++) {
        i = j + 4;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 3; j++) {
        i = j + 5;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        s = s - (L[(i * 8) + j + 4] * L[(j * 8) + j + 4]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 2; j++) {
        i = j + 6;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        s = s - (L[(i * 8) + j + 4] * L[(j * 8) + j + 4]);
        s = s - (L[(i * 8) + j + 5] * L[(j * 8) + j + 5]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 1; j++) {
        i = j + 7;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        s = s - (L[(i * 8) + j + 4] * L[(j * 8) + j + 4]);
        s = s - (L[(i * 8) + j + 5] * L[(j * 8) + j + 5]);
        s = s - (L[(i * 8) + j + 6] * L[(j * 8) + j + 6]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (i = 0; i <= 0; i++) {
        if (i == 0) {
            s = (pvtol_real)1 / L[0];
            s = s * s;
        } else {
            s = L[(i * 8)] / L[0];
        }
        s = s + (L[(i * 8) + 1] * L[1]);
        s = s + (L[(i * 8) + 2] * L[2]);
        s = s + (L[(i * 8) + 3] * L[3]);
        s = s + (L[(i * 8) + 4] * L[4]);
        s = s + (L[(i * 8) + 5] * L[5]);
        s = s + (L[(i * 8) + 6] * L[6]);
        s = s + (L[(i * 8) + 7] * L[7]);
        Yf[(i * 8)] = s;
        Yf[i] = s;
    }
    for (i = 0; i <= 1; i++) {
        if (i == 1) {
            s = (pvtol_real)1 / L[9];
            s = s * s;
        } else {
            s = L[(i * 8) + 1] / L[9];
        }
        s = s + (L[(i * 8) + 2] * L[10]);
        s = s + (L[(i * 8) + 3] * L[11]);
        s = s + (L[(i * 8) + 4] * L[12]);
        s = s + (L[(i * 8) + 5] * L[13]);
        s = s + (L[(i * 8) + 6] * L[14]);
        s = s + (L[(i * 8) + 7] * L[15]);
        Yf[(i * 8) + 1] = s;
        Yf[i + 8] = s;
    }
    for (i = 0; i <= 2; i++) {
        if (i == 2) {
            s = (pvtol_real)1 / L[18];
            s = s * s;
        } else {
            s = L[(i * 8) + 2] / L[18];
        }
        s = s + (L[(i * 8) + 3] * L[19]);
        s = s + (L[(i * 8) + 4] * L[20]);
        s = s + (L[(i * 8) + 5] * L[21]);
        s = s + (L[(i * 8) + 6] * L[22]);
        s = s + (L[(i * 8) + 7] * L[23]);
        Yf[(i * 8) + 2] = s;
        Yf[i + 16] = s;
    }
    for (i = 0; i <= 3; i++) {
        if (i == 3) {
            s = (pvtol_real)1 / L[27];
            s = s * s;
        } else {
            s = L[(i * 8) + 3] / L[27];
        }
        s = s + (L[(i * 8) + 4] * L[28]);
        s = s + (L[(i * 8) + 5] * L[29]);
        s = s + (L[(i * 8) + 6] * L[30]);
        s = s + (L[(i * 8) + 7] * L[31]);
        Yf[(i * 8) + 3] = s;
        Yf[i + 24] = s;
    }
    for (i = 0; i <= 4; i++) {
        if (i == 4) {
            s = (pvtol_real)1 / L[36];
            s = s * s;
        } else {
            s = L[(i * 8) + 4] / L[36];
        }
        s = s + (L[(i * 8) + 5] * L[37]);
        s = s + (L[(i * 8) + 6] * L[38]);
        s = s + (L[(i * 8) + 7] * L[39]);
        Yf[(i * 8) + 4] = s;
        Yf[i + 32] = s;
    }
    for (i = 0; i <= 5; i++) {
        if (i == 5) {
            s = (pvtol_real)1 / L[45];
            s = s * s;
        } else {
            s = L[(i * 8) + 5] / L[45];
        }
        s = s + (L[(i * 8) + 6] * L[46]);
        s = s + (L[(i * 8) + 7] * L[47]);
        Yf[(i * 8) + 5] = s;
        Yf[i + 40] = s;
    }
    for (i = 0; i <= 6; i++) {
        if (i == 6) {
            s = (pvtol_real)1 / L[54];
            s = s * s;
        } else {
            s = L[(i * 8) + 6] / L[54];
        }
        s = s + (L[(i * 8) + 7] * L[55]);
        Yf[(i * 8) + 6] = s;
        Yf[i + 48] = s;
    }
    for (i = 0; i <= 7; i++) {
        if (i == 7) {
            s = (pvtol_real)1 / L[63];
            s = s * s;
        } else {
            s = L[(i * 8) + 7] / L[63];
        }
        Yf[(i * 8) + 7] = s;
        Yf[i + 56] = s;
    }
    for (i = 0; i < 8; i++) {
        e[i] = x[i] - c[i];
    }
    for (i = 0; i < 8; i++) {
        s = Yf[i * 8] * e[0];
        for (j = 1; j < 8; j++) {
            s = s + (Yf[(i * 8) + j] * e[j]);
        }
        dy[i] = s;
    }
    k = 0;
    for (i = 0; i < 8; i++) {
        for (j = i; j < 8; j++) {
            dY[k] = Yf[(i * 8) + j];
            k++;
        }
    }
    for (i = 0; i < 8; i++) {
        s = Pp[i];
        if (i == 0) {
            piv[8] = s;
            L[0] = sqrt(s);
        } else {
            L[(i * 8)] = s / L[0];
        }
    }
    for (i = 1; i < 8; i++) {
        s = Pp[i + 8];
        s = s - (L[(i * 8)] * L[8]);
        if (i == 1) {
            piv[9] = s;
            L[9] = sqrt(s);
        } else {
            L[(i * 8) + 1] = s / L[9];
        }
    }
    for (i = 2; i < 8; i++) {
        s = Pp[i + 16];
        s = s - (L[(i * 8)] * L[16]);
        s = s - (L[(i * 8) + 1] * L[17]);
        if (i == 2) {
            piv[10] = s;
            L[18] = sqrt(s);
        } else {
            L[(i * 8) + 2] = s / L[18];
        }
    }
    for (i = 3; i < 8; i++) {
        s = Pp[i + 24];
        s = s - (L[(i * 8)] * L[24]);
        s = s - (L[(i * 8) + 1] * L[25]);
        s = s - (L[(i * 8) + 2] * L[26]);
        if (i == 3) {
            piv[11] = s;
            L[27] = sqrt(s);
        } else {
            L[(i * 8) + 3] = s / L[27];
        }
    }
    for (i = 4; i < 8; i++) {
        s = Pp[i + 32];
        s = s - (L[(i * 8)] * L[32]);
        s = s - (L[(i * 8) + 1] * L[33]);
        s = s - (L[(i * 8) + 2] * L[34]);
        s = s - (L[(i * 8) + 3] * L[35]);
        if (i == 4) {
            piv[12] = s;
            L[36] = sqrt(s);
        } else {
            L[(i * 8) + 4] = s / L[36];
        }
    }
    for (i = 5; i < 8; i++) {
        s = Pp[i + 40];
        s = s - (L[(i * 8)] * L[40]);
        s = s - (L[(i * 8) + 1] * L[41]);
        s = s - (L[(i * 8) + 2] * L[42]);
        s = s - (L[(i * 8) + 3] * L[43]);
        s = s - (L[(i * 8) + 4] * L[44]);
        if (i == 5) {
            piv[13] = s;
            L[45] = sqrt(s);
        } else {
            L[(i * 8) + 5] = s / L[45];
        }
    }
    for (i = 6; i < 8; i++) {
        s = Pp[i + 48];
        s = s - (L[(i * 8)] * L[48]);
        s = s - (L[(i * 8) + 1] * L[49]);
        s = s - (L[(i * 8) + 2] * L[50]);
        s = s - (L[(i * 8) + 3] * L[51]);
        s = s - (L[(i * 8) + 4] * L[52]);
        s = s - (L[(i * 8) + 5] * L[53]);
        if (i == 6) {
            piv[14] = s;
            L[54] = sqrt(s);
        } else {
            L[(i * 8) + 6] = s / L[54];
        }
    }
    for (i = 7; i < 8; i++) {
        s = Pp[i + 56];
        s = s - (L[(i * 8)] * L[56]);
        s = s - (L[(i * 8) + 1] * L[57]);
        s = s - (L[(i * 8) + 2] * L[58]);
        s = s - (L[(i * 8) + 3] * L[59]);
        s = s - (L[(i * 8) + 4] * L[60]);
        s = s - (L[(i * 8) + 5] * L[61]);
        s = s - (L[(i * 8) + 6] * L[62]);
        if (i == 7) {
            piv[15] = s;
            L[63] = sqrt(s);
        } else {
            L[(i * 8) + 7] = s / L[63];
        }
    }
    for (j = 0; j < 7; j++) {
        i = j + 1;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 6; j++) {
        i = j + 2;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 5; j++) {
        i = j + 3;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 4; j++) {
        i = j + 4;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 3; j++) {
        i = j + 5;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        s = s - (L[(i * 8) + j + 4] * L[(j * 8) + j + 4]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 2; j++) {
        i = j + 6;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        s = s - (L[(i * 8) + j + 4] * L[(j * 8) + j + 4]);
        s = s - (L[(i * 8) + j + 5] * L[(j * 8) + j + 5]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 1; j++) {
        i = j + 7;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        s = s - (L[(i * 8) + j + 4] * L[(j * 8) + j + 4]);
        s = s - (L[(i * 8) + j + 5] * L[(j * 8) + j + 5]);
        s = s - (L[(i * 8) + j + 6] * L[(j * 8) + j + 6]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (i = 0; i <= 0; i++) {
        if (i == 0) {
            s = (pvtol_real)1 / L[0];
            s = s * s;
        } else {
            s = L[(i * 8)] / L[0];
        }
        s = s + (L[(i * 8) + 1] * L[1]);
        s = s + (L[(i * 8) + 2] * L[2]);
        s = s + (L[(i * 8) + 3] * L[3]);
        s = s + (L[(i * 8) + 4] * L[4]);
        s = s + (L[(i * 8) + 5] * L[5]);
        s = s + (L[(i * 8) + 6] * L[6]);
        s = s + (L[(i * 8) + 7] * L[7]);
        Yf[(i * 8)] = s;
        Yf[i] = s;
    }
    for (i = 0; i <= 1; i++) {
        if (i == 1) {
            s = (pvtol_real)1 / L[9];
            s = s * s;
        } else {
            s = L[(i * 8) + 1] / L[9];
        }
        s = s + (L[(i * 8) + 2] * L[10]);
        s = s + (L[(i * 8) + 3] * L[11]);
        s = s + (L[(i * 8) + 4] * L[12]);
        s = s + (L[(i * 8) + 5] * L[13]);
        s = s + (L[(i * 8) + 6] * L[14]);
        s = s + (L[(i * 8) + 7] * L[15]);
        Yf[(i * 8) + 1] = s;
        Yf[i + 8] = s;
    }
    for (i = 0; i <= 2; i++) {
        if (i == 2) {
            s = (pvtol_real)1 / L[18];
            s = s * s;
        } else {
            s = L[(i * 8) + 2] / L[18];
        }
        s = s + (L[(i * 8) + 3] * L[19]);
        s = s + (L[(i * 8) + 4] * L[20]);
        s = s + (L[(i * 8) + 5] * L[21]);
        s = s + (L[(i * 8) + 6] * L[22]);
        s = s + (L[(i * 8) + 7] * L[23]);
        Yf[(i * 8) + 2] = s;
        Yf[i + 16] = s;
    }
    for (i = 0; i <= 3; i++) {
        if (i == 3) {
            s = (pvtol_real)1 / L[27];
            s = s * s;
        } else {
            s = L[(i * 8) + 3] / L[27];
        }
        s = s + (L[(i * 8) + 4] * L[28]);
        s = s + (L[(i * 8) + 5] * L[29]);
        s = s + (L[(i * 8) + 6] * L[30]);
        s = s + (L[(i * 8) + 7] * L[31]);
        Yf[(i * 8) + 3] = s;
        Yf[i + 24] = s;
    }
    for (i = 0; i <= 4; i++) {
        if (i == 4) {
            s = (pvtol_real)1 / L[36];
            s = s * s;
        } else {
            s = L[(i * 8) + 4] / L[36];
        }
        s = s + (L[(i * 8) + 5] * L[37]);
        s = s + (L[(i * 8) + 6] * L[38]);
        s = s + (L[(i * 8) + 7] * L[39]);
        Yf[(i * 8) + 4] = s;
        Yf[i + 32] = s;
    }
    for (i = 0; i <= 5; i++) {
        if (i == 5) {
            s = (pvtol_real)1 / L[45];
            s = s * s;
        } else {
            s = L[(i * 8) + 5] / L[45];
        }
        s = s + (L[(i * 8) + 6] * L[46]);
        s = s + (L[(i * 8) + 7] * L[47]);
        Yf[(i * 8) + 5] = s;
        Yf[i + 40] = s;
    }
    for (i = 0; i <= 6; i++) {
        if (i == 6) {
            s = (pvtol_real)1 / L[54];
            s = s * s;
        } else {
            s = L[(i * 8) + 6] / L[54];
        }
        s = s + (L[(i * 8) + 7] * L[55]);
        Yf[(i * 8) + 6] = s;
        Yf[i + 48] = s;
    }
    for (i = 0; i <= 7; i++) {
        if (i == 7) {
            s = (pvtol_real)1 / L[63];
            s = s * s;
        } else {
            s = L[(i * 8) + 7] / L[63];
        }
        Yf[(i * 8) + 7] = s;
        Yf[i + 56] = s;
    }
    for (i = 0; i < 8; i++) {
        e[i] = xp[i] - c[i];
    }
    for (i = 0; i < 8; i++) {
        s = Yf[i * 8] * e[0];
        for (j = 1; j < 8; j++) {
            s = s + (Yf[(i * 8) + j] * e[j]);
        }
        z[i] = s;
    }
    for (i = 0; i < 8; i++) {
        dy[i] = dy[i] - z[i];
    }
    k = 0;
    for (i = 0; i < 8; i++) {
        for (j = i; j < 8; j++) {
            dY[k] = dY[k] - Yf[(i * 8) + j];
            k++;
        }
    }
    return 0;
}

/* pvtol_kern_fuse_finish:(Pc[8x8],dY[36],dy[8],c[8])->(x[8],P[8x8],piv[16]) */
int pvtol_kern_fuse_finish(const pvtol_real Pc[64], const pvtol_real dY[36], const pvtol_real dy[8],
                           const pvtol_real c[8], pvtol_real x[8], pvtol_real P[64],
                           pvtol_real piv[16])
{
    pvtol_real L[64]; /* the Cholesky factor by rows, then its inverse's columns */
    pvtol_real s;
    int i;
    int j;
    int k;
    for (i = 0; i < 8; i++) {
        s = Pc[i];
        if (i == 0) {
            piv[0] = s;
            L[0] = sqrt(s);
        } else {
            L[(i * 8)] = s / L[0];
        }
    }
    for (i = 1; i < 8; i++) {
        s = Pc[i + 8];
        s = s - (L[(i * 8)] * L[8]);
        if (i == 1) {
            piv[1] = s;
            L[9] = sqrt(s);
        } else {
            L[(i * 8) + 1] = s / L[9];
        }
    }
    for (i = 2; i < 8; i++) {
        s = Pc[i + 16];
        s = s - (L[(i * 8)] * L[16]);
        s = s - (L[(i * 8) + 1] * L[17]);
        if (i == 2) {
            piv[2] = s;
            L[18] = sqrt(s);
        } else {
            L[(i * 8) + 2] = s / L[18];
        }
    }
    for (i = 3; i < 8; i++) {
        s = Pc[i + 24];
        s = s - (L[(i * 8)] * L[24]);
        s = s - (L[(i * 8) + 1] * L[25]);
        s = s - (L[(i * 8) + 2] * L[26]);
        if (i == 3) {
            piv[3] = s;
            L[27] = sqrt(s);
        } else {
            L[(i * 8) + 3] = s / L[27];
        }
    }
    for (i = 4; i < 8; i++) {
        s = Pc[i + 32];
        s = s - (L[(i * 8)] * L[32]);
        s = s - (L[(i * 8) + 1] * L[33]);
        s = s - (L[(i * 8) + 2] * L[34]);
        s = s - (L[(i * 8) + 3] * L[35]);
        if (i == 4) {
            piv[4] = s;
            L[36] = sqrt(s);
        } else {
            L[(i * 8) + 4] = s / L[36];
        }
    }
    for (i = 5; i < 8; i++) {
        s = Pc[i + 40];
        s = s - (L[(i * 8)] * L[40]);
        s = s - (L[(i * 8) + 1] * L[41]);
        s = s - (L[(i * 8) + 2] * L[42]);
        s = s - (L[(i * 8) + 3] * L[43]);
        s = s - (L[(i * 8) + 4] * L[44]);
        if (i == 5) {
            piv[5] = s;
            L[45] = sqrt(s);
        } else {
            L[(i * 8) + 5] = s / L[45];
        }
    }
    for (i = 6; i < 8; i++) {
        s = Pc[i + 48];
        s = s - (L[(i * 8)] * L[48]);
        s = s - (L[(i * 8) + 1] * L[49]);
        s = s - (L[(i * 8) + 2] * L[50]);
        s = s - (L[(i * 8) + 3] * L[51]);
        s = s - (L[(i * 8) + 4] * L[52]);
        s = s - (L[(i * 8) + 5] * L[53]);
        if (i == 6) {
            piv[6] = s;
            L[54] = sqrt(s);
        } else {
            L[(i * 8) + 6] = s / L[54];
        }
    }
    for (i = 7; i < 8; i++) {
        s = Pc[i + 56];
        s = s - (L[(i * 8)] * L[56]);
        s = s - (L[(i * 8) + 1] * L[57]);
        s = s - (L[(i * 8) + 2] * L[58]);
        s = s - (L[(i * 8) + 3] * L[59]);
        s = s - (L[(i * 8) + 4] * L[60]);
        s = s - (L[(i * 8) + 5] * L[61]);
        s = s - (L[(i * 8) + 6] * L[62]);
        if (i == 7) {
            piv[7] = s;
            L[63] = sqrt(s);
        } else {
            L[(i * 8) + 7] = s / L[63];
        }
    }
    for (j = 0; j < 7; j++) {
        i = j + 1;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 6; j++) {
        i = j + 2;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 5; j++) {
        i = j + 3;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 4; j++) {
        i = j + 4;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 3; j++) {
        i = j + 5;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        s = s - (L[(i * 8) + j + 4] * L[(j * 8) + j + 4]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 2; j++) {
        i = j + 6;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        s = s - (L[(i * 8) + j + 4] * L[(j * 8) + j + 4]);
        s = s - (L[(i * 8) + j + 5] * L[(j * 8) + j + 5]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 1; j++) {
        i = j + 7;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        s = s - (L[(i * 8) + j + 4] * L[(j * 8) + j + 4]);
        s = s - (L[(i * 8) + j + 5] * L[(j * 8) + j + 5]);
        s = s - (L[(i * 8) + j + 6] * L[(j * 8) + j + 6]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (i = 0; i <= 0; i++) {
        if (i == 0) {
            s = (pvtol_real)1 / L[0];
            s = s * s;
        } else {
            s = L[(i * 8)] / L[0];
        }
        s = s + (L[(i * 8) + 1] * L[1]);
        s = s + (L[(i * 8) + 2] * L[2]);
        s = s + (L[(i * 8) + 3] * L[3]);
        s = s + (L[(i * 8) + 4] * L[4]);
        s = s + (L[(i * 8) + 5] * L[5]);
        s = s + (L[(i * 8) + 6] * L[6]);
        s = s + (L[(i * 8) + 7] * L[7]);
        P[(i * 8)] = s;
        P[i] = s;
    }
    for (i = 0; i <= 1; i++) {
        if (i == 1) {
            s = (pvtol_real)1 / L[9];
            s = s * s;
        } else {
            s = L[(i * 8) + 1] / L[9];
        }
        s = s + (L[(i * 8) + 2] * L[10]);
        s = s + (L[(i * 8) + 3] * L[11]);
        s = s + (L[(i * 8) + 4] * L[12]);
        s = s + (L[(i * 8) + 5] * L[13]);
        s = s + (L[(i * 8) + 6] * L[14]);
        s = s + (L[(i * 8) + 7] * L[15]);
        P[(i * 8) + 1] = s;
        P[i + 8] = s;
    }
    for (i = 0; i <= 2; i++) {
        if (i == 2) {
            s = (pvtol_real)1 / L[18];
            s = s * s;
        } else {
            s = L[(i * 8) + 2] / L[18];
        }
        s = s + (L[(i * 8) + 3] * L[19]);
        s = s + (L[(i * 8) + 4] * L[20]);
        s = s + (L[(i * 8) + 5] * L[21]);
        s = s + (L[(i * 8) + 6] * L[22]);
        s = s + (L[(i * 8) + 7] * L[23]);
        P[(i * 8) + 2] = s;
        P[i + 16] = s;
    }
    for (i = 0; i <= 3; i++) {
        if (i == 3) {
            s = (pvtol_real)1 / L[27];
            s = s * s;
        } else {
            s = L[(i * 8) + 3] / L[27];
        }
        s = s + (L[(i * 8) + 4] * L[28]);
        s = s + (L[(i * 8) + 5] * L[29]);
        s = s + (L[(i * 8) + 6] * L[30]);
        s = s + (L[(i * 8) + 7] * L[31]);
        P[(i * 8) + 3] = s;
        P[i + 24] = s;
    }
    for (i = 0; i <= 4; i++) {
        if (i == 4) {
            s = (pvtol_real)1 / L[36];
            s = s * s;
        } else {
            s = L[(i * 8) + 4] / L[36];
        }
        s = s + (L[(i * 8) + 5] * L[37]);
        s = s + (L[(i * 8) + 6] * L[38]);
        s = s + (L[(i * 8) + 7] * L[39]);
        P[(i * 8) + 4] = s;
        P[i + 32] = s;
    }
    for (i = 0; i <= 5; i++) {
        if (i == 5) {
            s = (pvtol_real)1 / L[45];
            s = s * s;
        } else {
            s = L[(i * 8) + 5] / L[45];
        }
        s = s + (L[(i * 8) + 6] * L[46]);
        s = s + (L[(i * 8) + 7] * L[47]);
        P[(i * 8) + 5] = s;
        P[i + 40] = s;
    }
    for (i = 0; i <= 6; i++) {
        if (i == 6) {
            s = (pvtol_real)1 / L[54];
            s = s * s;
        } else {
            s = L[(i * 8) + 6] / L[54];
        }
        s = s + (L[(i * 8) + 7] * L[55]);
        P[(i * 8) + 6] = s;
        P[i + 48] = s;
    }
    for (i = 0; i <= 7; i++) {
        if (i == 7) {
            s = (pvtol_real)1 / L[63];
            s = s * s;
        } else {
            s = L[(i * 8) + 7] / L[63];
        }
        P[(i * 8) + 7] = s;
        P[i + 56] = s;
    }
    k = 0;
    for (i = 0; i < 8; i++) {
        for (j = i; j < 8; j++) {
            s = P[(i * 8) + j] + dY[k];
            P[(i * 8) + j] = s;
            P[(j * 8) + i] = s;
            k++;
        }
    }
    for (i = 0; i < 8; i++) {
        s = P[i];
        if (i == 0) {
            piv[8] = s;
            L[0] = sqrt(s);
        } else {
            L[(i * 8)] = s / L[0];
        }
    }
    for (i = 1; i < 8; i++) {
        s = P[i + 8];
        s = s - (L[(i * 8)] * L[8]);
        if (i == 1) {
            piv[9] = s;
            L[9] = sqrt(s);
        } else {
            L[(i * 8) + 1] = s / L[9];
        }
    }
    for (i = 2; i < 8; i++) {
        s = P[i + 16];
        s = s - (L[(i * 8)] * L[16]);
        s = s - (L[(i * 8) + 1] * L[17]);
        if (i == 2) {
            piv[10] = s;
            L[18] = sqrt(s);
        } else {
            L[(i * 8) + 2] = s / L[18];
        }
    }
    for (i = 3; i < 8; i++) {
        s = P[i + 24];
        s = s - (L[(i * 8)] * L[24]);
        s = s - (L[(i * 8) + 1] * L[25]);
        s = s - (L[(i * 8) + 2] * L[26]);
        if (i == 3) {
            piv[11] = s;
            L[27] = sqrt(s);
        } else {
            L[(i * 8) + 3] = s / L[27];
        }
    }
    for (i = 4; i < 8; i++) {
        s = P[i + 32];
        s = s - (L[(i * 8)] * L[32]);
        s = s - (L[(i * 8) + 1] * L[33]);
        s = s - (L[(i * 8) + 2] * L[34]);
        s = s - (L[(i * 8) + 3] * L[35]);
        if (i == 4) {
            piv[12] = s;
            L[36] = sqrt(s);
        } else {
            L[(i * 8) + 4] = s / L[36];
        }
    }
    for (i = 5; i < 8; i++) {
        s = P[i + 40];
        s = s - (L[(i * 8)] * L[40]);
        s = s - (L[(i * 8) + 1] * L[41]);
        s = s - (L[(i * 8) + 2] * L[42]);
        s = s - (L[(i * 8) + 3] * L[43]);
        s = s - (L[(i * 8) + 4] * L[44]);
        if (i == 5) {
            piv[13] = s;
            L[45] = sqrt(s);
        } else {
            L[(i * 8) + 5] = s / L[45];
        }
    }
    for (i = 6; i < 8; i++) {
        s = P[i + 48];
        s = s - (L[(i * 8)] * L[48]);
        s = s - (L[(i * 8) + 1] * L[49]);
        s = s - (L[(i * 8) + 2] * L[50]);
        s = s - (L[(i * 8) + 3] * L[51]);
        s = s - (L[(i * 8) + 4] * L[52]);
        s = s - (L[(i * 8) + 5] * L[53]);
        if (i == 6) {
            piv[14] = s;
            L[54] = sqrt(s);
        } else {
            L[(i * 8) + 6] = s / L[54];
        }
    }
    for (i = 7; i < 8; i++) {
        s = P[i + 56];
        s = s - (L[(i * 8)] * L[56]);
        s = s - (L[(i * 8) + 1] * L[57]);
        s = s - (L[(i * 8) + 2] * L[58]);
        s = s - (L[(i * 8) + 3] * L[59]);
        s = s - (L[(i * 8) + 4] * L[60]);
        s = s - (L[(i * 8) + 5] * L[61]);
        s = s - (L[(i * 8) + 6] * L[62]);
        if (i == 7) {
            piv[15] = s;
            L[63] = sqrt(s);
        } else {
            L[(i * 8) + 7] = s / L[63];
        }
    }
    for (j = 0; j < 7; j++) {
        i = j + 1;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 6; j++) {
        i = j + 2;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 5; j++) {
        i = j + 3;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 4; j++) {
        i = j + 4;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 3; j++) {
        i = j + 5;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        s = s - (L[(i * 8) + j + 4] * L[(j * 8) + j + 4]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 2; j++) {
        i = j + 6;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        s = s - (L[(i * 8) + j + 4] * L[(j * 8) + j + 4]);
        s = s - (L[(i * 8) + j + 5] * L[(j * 8) + j + 5]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (j = 0; j < 1; j++) {
        i = j + 7;
        s = -(L[(i * 8) + j] / L[(j * 8) + j]);
        s = s - (L[(i * 8) + j + 1] * L[(j * 8) + j + 1]);
        s = s - (L[(i * 8) + j + 2] * L[(j * 8) + j + 2]);
        s = s - (L[(i * 8) + j + 3] * L[(j * 8) + j + 3]);
        s = s - (L[(i * 8) + j + 4] * L[(j * 8) + j + 4]);
        s = s - (L[(i * 8) + j + 5] * L[(j * 8) + j + 5]);
        s = s - (L[(i * 8) + j + 6] * L[(j * 8) + j + 6]);
        L[(j * 8) + i] = s / L[(i * 8) + i];
    }
    for (i = 0; i <= 0; i++) {
        if (i == 0) {
            s = (pvtol_real)1 / L[0];
            s = s * s;
        } else {
            s = L[(i * 8)] / L[0];
        }
        s = s + (L[(i * 8) + 1] * L[1]);
        s = s + (L[(i * 8) + 2] * L[2]);
        s = s + (L[(i * 8) + 3] * L[3]);
        s = s + (L[(i * 8) + 4] * L[4]);
        s = s + (L[(i * 8) + 5] * L[5]);
        s = s + (L[(i * 8) + 6] * L[6]);
        s = s + (L[(i * 8) + 7] * L[7]);
        P[(i * 8)] = s;
        P[i] = s;
    }
    for (i = 0; i <= 1; i++) {
        if (i == 1) {
            s = (pvtol_real)1 / L[9];
            s = s * s;
        } else {
            s = L[(i * 8) + 1] / L[9];
        }
        s = s + (L[(i * 8) + 2] * L[10]);
        s = s + (L[(i * 8) + 3] * L[11]);
        s = s + (L[(i * 8) + 4] * L[12]);
        s = s + (L[(i * 8) + 5] * L[13]);
        s = s + (L[(i * 8) + 6] * L[14]);
        s = s + (L[(i * 8) + 7] * L[15]);
        P[(i * 8) + 1] = s;
        P[i + 8] = s;
    }
    for (i = 0; i <= 2; i++) {
        if (i == 2) {
            s = (pvtol_real)1 / L[18];
            s = s * s;
        } else {
            s = L[(i * 8) + 2] / L[18];
        }
        s = s + (L[(i * 8) + 3] * L[19]);
        s = s + (L[(i * 8) + 4] * L[20]);
        s = s + (L[(i * 8) + 5] * L[21]);
        s = s + (L[(i * 8) + 6] * L[22]);
        s = s + (L[(i * 8) + 7] * L[23]);
        P[(i * 8) + 2] = s;
        P[i + 16] = s;
    }
    for (i = 0; i <= 3; i++) {
        if (i == 3) {
            s = (pvtol_real)1 / L[27];
            s = s * s;
        } else {
            s = L[(i * 8) + 3] / L[27];
        }
        s = s + (L[(i * 8) + 4] * L[28]);
        s = s + (L[(i * 8) + 5] * L[29]);
        s = s + (L[(i * 8) + 6] * L[30]);
        s = s + (L[(i * 8) + 7] * L[31]);
        P[(i * 8) + 3] = s;
        P[i + 24] = s;
    }
    for (i = 0; i <= 4; i++) {
        if (i == 4) {
            s = (pvtol_real)1 / L[36];
            s = s * s;
        } else {
            s = L[(i * 8) + 4] / L[36];
        }
        s = s + (L[(i * 8) + 5] * L[37]);
        s = s + (L[(i * 8) + 6] * L[38]);
        s = s + (L[(i * 8) + 7] * L[39]);
        P[(i * 8) + 4] = s;
        P[i + 32] = s;
    }
    for (i = 0; i <= 5; i++) {
        if (i == 5) {
            s = (pvtol_real)1 / L[45];
            s = s * s;
        } else {
            s = L[(i * 8) + 5] / L[45];
        }
        s = s + (L[(i * 8) + 6] * L[46]);
        s = s + (L[(i * 8) + 7] * L[47]);
        P[(i * 8) + 5] = s;
        P[i + 40] = s;
    }
    for (i = 0; i <= 6; i++) {
        if (i == 6) {
            s = (pvtol_real)1 / L[54];
            s = s * s;
        } else {
            s = L[(i * 8) + 6] / L[54];
        }
        s = s + (L[(i * 8) + 7] * L[55]);
        P[(i * 8) + 6] = s;
        P[i + 48] = s;
    }
    for (i = 0; i <= 7; i++) {
        if (i == 7) {
            s = (pvtol_real)1 / L[63];
            s = s * s;
        } else {
            s = L[(i * 8) + 7] / L[63];
        }
        P[(i * 8) + 7] = s;
        P[i + 56] = s;
    }
    for (i = 0; i < 8; i++) {
        s = P[i * 8] * dy[0];
        for (j = 1; j < 8; j++) {
            s = s + (P[(i * 8) + j] * dy[j]);
        }
        x[i] = c[i] + s;
    }
    return 0;
}
