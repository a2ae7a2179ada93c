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
    pvtol_real D[64];
    pvtol_real W[64];
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
    k = 0;
    for (i = 0; i < 8; i++) {
        for (j = i; j < 8; j++) {
            P[(i * 8) + j] = dY[k];
            P[(j * 8) + i] = dY[k];
            k++;
        }
    }
    for (k = 0; k < 8; k++) {
        s = P[(k * 8)] * L[0];
        s = s + (P[(k * 8) + 1] * L[8]);
        s = s + (P[(k * 8) + 2] * L[16]);
        s = s + (P[(k * 8) + 3] * L[24]);
        s = s + (P[(k * 8) + 4] * L[32]);
        s = s + (P[(k * 8) + 5] * L[40]);
        s = s + (P[(k * 8) + 6] * L[48]);
        s = s + (P[(k * 8) + 7] * L[56]);
        W[(k * 8)] = s;
    }
    for (k = 0; k < 8; k++) {
        s = P[(k * 8) + 1] * L[9];
        s = s + (P[(k * 8) + 2] * L[17]);
        s = s + (P[(k * 8) + 3] * L[25]);
        s = s + (P[(k * 8) + 4] * L[33]);
        s = s + (P[(k * 8) + 5] * L[41]);
        s = s + (P[(k * 8) + 6] * L[49]);
        s = s + (P[(k * 8) + 7] * L[57]);
        W[(k * 8) + 1] = s;
    }
    for (k = 0; k < 8; k++) {
        s = P[(k * 8) + 2] * L[18];
        s = s + (P[(k * 8) + 3] * L[26]);
        s = s + (P[(k * 8) + 4] * L[34]);
        s = s + (P[(k * 8) + 5] * L[42]);
        s = s + (P[(k * 8) + 6] * L[50]);
        s = s + (P[(k * 8) + 7] * L[58]);
        W[(k * 8) + 2] = s;
    }
    for (k = 0; k < 8; k++) {
        s = P[(k * 8) + 3] * L[27];
        s = s + (P[(k * 8) + 4] * L[35]);
        s = s + (P[(k * 8) + 5] * L[43]);
        s = s + (P[(k * 8) + 6] * L[51]);
        s = s + (P[(k * 8) + 7] * L[59]);
        W[(k * 8) + 3] = s;
    }
    for (k = 0; k < 8; k++) {
        s = P[(k * 8) + 4] * L[36];
        s = s + (P[(k * 8) + 5] * L[44]);
        s = s + (P[(k * 8) + 6] * L[52]);
        s = s + (P[(k * 8) + 7] * L[60]);
        W[(k * 8) + 4] = s;
    }
    for (k = 0; k < 8; k++) {
        s = P[(k * 8) + 5] * L[45];
        s = s + (P[(k * 8) + 6] * L[53]);
        s = s + (P[(k * 8) + 7] * L[61]);
        W[(k * 8) + 5] = s;
    }
    for (k = 0; k < 8; k++) {
        s = P[(k * 8) + 6] * L[54];
        s = s + (P[(k * 8) + 7] * L[62]);
        W[(k * 8) + 6] = s;
    }
    for (k = 0; k < 8; k++) {
        s = P[(k * 8) + 7] * L[63];
        W[(k * 8) + 7] = s;
    }
    for (j = 0; j < 8; j++) {
        s = L[0] * W[j];
        s = s + (L[8] * W[j + 8]);
        s = s + (L[16] * W[j + 16]);
        s = s + (L[24] * W[j + 24]);
        s = s + (L[32] * W[j + 32]);
        s = s + (L[40] * W[j + 40]);
        s = s + (L[48] * W[j + 48]);
        s = s + (L[56] * W[j + 56]);
        if (j == 0) {
            s = (pvtol_real)1 + s;
        }
        D[j] = s;
        D[(j * 8)] = s;
    }
    for (j = 1; j < 8; j++) {
        s = L[9] * W[j + 8];
        s = s + (L[17] * W[j + 16]);
        s = s + (L[25] * W[j + 24]);
        s = s + (L[33] * W[j + 32]);
        s = s + (L[41] * W[j + 40]);
        s = s + (L[49] * W[j + 48]);
        s = s + (L[57] * W[j + 56]);
        if (j == 1) {
            s = (pvtol_real)1 + s;
        }
        D[j + 8] = s;
        D[(j * 8) + 1] = s;
    }
    for (j = 2; j < 8; j++) {
        s = L[18] * W[j + 16];
        s = s + (L[26] * W[j + 24]);
        s = s + (L[34] * W[j + 32]);
        s = s + (L[42] * W[j + 40]);
        s = s + (L[50] * W[j + 48]);
        s = s + (L[58] * W[j + 56]);
        if (j == 2) {
            s = (pvtol_real)1 + s;
        }
        D[j + 16] = s;
        D[(j * 8) + 2] = s;
    }
    for (j = 3; j < 8; j++) {
        s = L[27] * W[j + 24];
        s = s + (L[35] * W[j + 32]);
        s = s + (L[43] * W[j + 40]);
        s = s + (L[51] * W[j + 48]);
        s = s + (L[59] * W[j + 56]);
        if (j == 3) {
            s = (pvtol_real)1 + s;
        }
        D[j + 24] = s;
        D[(j * 8) + 3] = s;
    }
    for (j = 4; j < 8; j++) {
        s = L[36] * W[j + 32];
        s = s + (L[44] * W[j + 40]);
        s = s + (L[52] * W[j + 48]);
        s = s + (L[60] * W[j + 56]);
        if (j == 4) {
            s = (pvtol_real)1 + s;
        }
        D[j + 32] = s;
        D[(j * 8) + 4] = s;
    }
    for (j = 5; j < 8; j++) {
        s = L[45] * W[j + 40];
        s = s + (L[53] * W[j + 48]);
        s = s + (L[61] * W[j + 56]);
        if (j == 5) {
            s = (pvtol_real)1 + s;
        }
        D[j + 40] = s;
        D[(j * 8) + 5] = s;
    }
    for (j = 6; j < 8; j++) {
        s = L[54] * W[j + 48];
        s = s + (L[62] * W[j + 56]);
        if (j == 6) {
            s = (pvtol_real)1 + s;
        }
        D[j + 48] = s;
        D[(j * 8) + 6] = s;
    }
    for (j = 7; j < 8; j++) {
        s = L[63] * W[j + 56];
        if (j == 7) {
            s = (pvtol_real)1 + s;
        }
        D[j + 56] = s;
        D[(j * 8) + 7] = s;
    }
    for (i = 0; i < 8; i++) {
        s = D[i];
        if (i == 0) {
            piv[8] = s;
            W[0] = sqrt(s);
        } else {
            W[(i * 8)] = s / W[0];
        }
    }
    for (i = 1; i < 8; i++) {
        s = D[i + 8];
        s = s - (W[(i * 8)] * W[8]);
        if (i == 1) {
            piv[9] = s;
            W[9] = sqrt(s);
        } else {
            W[(i * 8) + 1] = s / W[9];
        }
    }
    for (i = 2; i < 8; i++) {
        s = D[i + 16];
        s = s - (W[(i * 8)] * W[16]);
        s = s - (W[(i * 8) + 1] * W[17]);
        if (i == 2) {
            piv[10] = s;
            W[18] = sqrt(s);
        } else {
            W[(i * 8) + 2] = s / W[18];
        }
    }
    for (i = 3; i < 8; i++) {
        s = D[i + 24];
        s = s - (W[(i * 8)] * W[24]);
        s = s - (W[(i * 8) + 1] * W[25]);
        s = s - (W[(i * 8) + 2] * W[26]);
        if (i == 3) {
            piv[11] = s;
            W[27] = sqrt(s);
        } else {
            W[(i * 8) + 3] = s / W[27];
        }
    }
    for (i = 4; i < 8; i++) {
        s = D[i + 32];
        s = s - (W[(i * 8)] * W[32]);
        s = s - (W[(i * 8) + 1] * W[33]);
        s = s - (W[(i * 8) + 2] * W[34]);
        s = s - (W[(i * 8) + 3] * W[35]);
        if (i == 4) {
            piv[12] = s;
            W[36] = sqrt(s);
        } else {
            W[(i * 8) + 4] = s / W[36];
        }
    }
    for (i = 5; i < 8; i++) {
        s = D[i + 40];
        s = s - (W[(i * 8)] * W[40]);
        s = s - (W[(i * 8) + 1] * W[41]);
        s = s - (W[(i * 8) + 2] * W[42]);
        s = s - (W[(i * 8) + 3] * W[43]);
        s = s - (W[(i * 8) + 4] * W[44]);
        if (i == 5) {
            piv[13] = s;
            W[45] = sqrt(s);
        } else {
            W[(i * 8) + 5] = s / W[45];
        }
    }
    for (i = 6; i < 8; i++) {
        s = D[i + 48];
        s = s - (W[(i * 8)] * W[48]);
        s = s - (W[(i * 8) + 1] * W[49]);
        s = s - (W[(i * 8) + 2] * W[50]);
        s = s - (W[(i * 8) + 3] * W[51]);
        s = s - (W[(i * 8) + 4] * W[52]);
        s = s - (W[(i * 8) + 5] * W[53]);
        if (i == 6) {
            piv[14] = s;
            W[54] = sqrt(s);
        } else {
            W[(i * 8) + 6] = s / W[54];
        }
    }
    for (i = 7; i < 8; i++) {
        s = D[i + 56];
        s = s - (W[(i * 8)] * W[56]);
        s = s - (W[(i * 8) + 1] * W[57]);
        s = s - (W[(i * 8) + 2] * W[58]);
        s = s - (W[(i * 8) + 3] * W[59]);
        s = s - (W[(i * 8) + 4] * W[60]);
        s = s - (W[(i * 8) + 5] * W[61]);
        s = s - (W[(i * 8) + 6] * W[62]);
        if (i == 7) {
            piv[15] = s;
            W[63] = sqrt(s);
        } else {
            W[(i * 8) + 7] = s / W[63];
        }
    }
    for (j = 0; j < 7; j++) {
        i = j + 1;
        s = -(W[(i * 8) + j] / W[(j * 8) + j]);
        W[(j * 8) + i] = s / W[(i * 8) + i];
    }
    for (j = 0; j < 6; j++) {
        i = j + 2;
        s = -(W[(i * 8) + j] / W[(j * 8) + j]);
        s = s - (W[(i * 8) + j + 1] * W[(j * 8) + j + 1]);
        W[(j * 8) + i] = s / W[(i * 8) + i];
    }
    for (j = 0; j < 5; j++) {
        i = j + 3;
        s = -(W[(i * 8) + j] / W[(j * 8) + j]);
        s = s - (W[(i * 8) + j + 1] * W[(j * 8) + j + 1]);
        s = s - (W[(i * 8) + j + 2] * W[(j * 8) + j + 2]);
        W[(j * 8) + i] = s / W[(i * 8) + i];
    }
    for (j = 0; j < 4; j++) {
        i = j + 4;
        s = -(W[(i * 8) + j] / W[(j * 8) + j]);
        s = s - (W[(i * 8) + j + 1] * W[(j * 8) + j + 1]);
        s = s - (W[(i * 8) + j + 2] * W[(j * 8) + j + 2]);
        s = s - (W[(i * 8) + j + 3] * W[(j * 8) + j + 3]);
        W[(j * 8) + i] = s / W[(i * 8) + i];
    }
    for (j = 0; j < 3; j++) {
        i = j + 5;
        s = -(W[(i * 8) + j] / W[(j * 8) + j]);
        s = s - (W[(i * 8) + j + 1] * W[(j * 8) + j + 1]);
        s = s - (W[(i * 8) + j + 2] * W[(j * 8) + j + 2]);
        s = s - (W[(i * 8) + j + 3] * W[(j * 8) + j + 3]);
        s = s - (W[(i * 8) + j + 4] * W[(j * 8) + j + 4]);
        W[(j * 8) + i] = s / W[(i * 8) + i];
    }
    for (j = 0; j < 2; j++) {
        i = j + 6;
        s = -(W[(i * 8) + j] / W[(j * 8) + j]);
        s = s - (W[(i * 8) + j + 1] * W[(j * 8) + j + 1]);
        s = s - (W[(i * 8) + j + 2] * W[(j * 8) + j + 2]);
        s = s - (W[(i * 8) + j + 3] * W[(j * 8) + j + 3]);
        s = s - (W[(i * 8) + j + 4] * W[(j * 8) + j + 4]);
        s = s - (W[(i * 8) + j + 5] * W[(j * 8) + j + 5]);
        W[(j * 8) + i] = s / W[(i * 8) + i];
    }
    for (j = 0; j < 1; j++) {
        i = j + 7;
        s = -(W[(i * 8) + j] / W[(j * 8) + j]);
        s = s - (W[(i * 8) + j + 1] * W[(j * 8) + j + 1]);
        s = s - (W[(i * 8) + j + 2] * W[(j * 8) + j + 2]);
        s = s - (W[(i * 8) + j + 3] * W[(j * 8) + j + 3]);
        s = s - (W[(i * 8) + j + 4] * W[(j * 8) + j + 4]);
        s = s - (W[(i * 8) + j + 5] * W[(j * 8) + j + 5]);
        s = s - (W[(i * 8) + j + 6] * W[(j * 8) + j + 6]);
        W[(j * 8) + i] = s / W[(i * 8) + i];
    }
    for (i = 0; i <= 0; i++) {
        if (i == 0) {
            s = (pvtol_real)1 / W[0];
            s = s * s;
        } else {
            s = W[(i * 8)] / W[0];
        }
        s = s + (W[(i * 8) + 1] * W[1]);
        s = s + (W[(i * 8) + 2] * W[2]);
        s = s + (W[(i * 8) + 3] * W[3]);
        s = s + (W[(i * 8) + 4] * W[4]);
        s = s + (W[(i * 8) + 5] * W[5]);
        s = s + (W[(i * 8) + 6] * W[6]);
        s = s + (W[(i * 8) + 7] * W[7]);
        P[(i * 8)] = s;
        P[i] = s;
    }
    for (i = 0; i <= 1; i++) {
        if (i == 1) {
            s = (pvtol_real)1 / W[9];
            s = s * s;
        } else {
            s = W[(i * 8) + 1] / W[9];
        }
        s = s + (W[(i * 8) + 2] * W[10]);
        s = s + (W[(i * 8) + 3] * W[11]);
        s = s + (W[(i * 8) + 4] * W[12]);
        s = s + (W[(i * 8) + 5] * W[13]);
        s = s + (W[(i * 8) + 6] * W[14]);
        s = s + (W[(i * 8) + 7] * W[15]);
        P[(i * 8) + 1] = s;
        P[i + 8] = s;
    }
    for (i = 0; i <= 2; i++) {
        if (i == 2) {
            s = (pvtol_real)1 / W[18];
            s = s * s;
        } else {
            s = W[(i * 8) + 2] / W[18];
        }
        s = s + (W[(i * 8) + 3] * W[19]);
        s = s + (W[(i * 8) + 4] * W[20]);
        s = s + (W[(i * 8) + 5] * W[21]);
        s = s + (W[(i * 8) + 6] * W[22]);
        s = s + (W[(i * 8) + 7] * W[23]);
        P[(i * 8) + 2] = s;
        P[i + 16] = s;
    }
    for (i = 0; i <= 3; i++) {
        if (i == 3) {
            s = (pvtol_real)1 / W[27];
            s = s * s;
        } else {
            s = W[(i * 8) + 3] / W[27];
        }
        s = s + (W[(i * 8) + 4] * W[28]);
        s = s + (W[(i * 8) + 5] * W[29]);
        s = s + (W[(i * 8) + 6] * W[30]);
        s = s + (W[(i * 8) + 7] * W[31]);
        P[(i * 8) + 3] = s;
        P[i + 24] = s;
    }
    for (i = 0; i <= 4; i++) {
        if (i == 4) {
            s = (pvtol_real)1 / W[36];
            s = s * s;
        } else {
            s = W[(i * 8) + 4] / W[36];
        }
        s = s + (W[(i * 8) + 5] * W[37]);
        s = s + (W[(i * 8) + 6] * W[38]);
        s = s + (W[(i * 8) + 7] * W[39]);
        P[(i * 8) + 4] = s;
        P[i + 32] = s;
    }
    for (i = 0; i <= 5; i++) {
        if (i == 5) {
            s = (pvtol_real)1 / W[45];
            s = s * s;
        } else {
            s = W[(i * 8) + 5] / W[45];
        }
        s = s + (W[(i * 8) + 6] * W[46]);
        s = s + (W[(i * 8) + 7] * W[47]);
        P[(i * 8) + 5] = s;
        P[i + 40] = s;
    }
    for (i = 0; i <= 6; i++) {
        if (i == 6) {
            s = (pvtol_real)1 / W[54];
            s = s * s;
        } else {
            s = W[(i * 8) + 6] / W[54];
        }
        s = s + (W[(i * 8) + 7] * W[55]);
        P[(i * 8) + 6] = s;
        P[i + 48] = s;
    }
    for (i = 0; i <= 7; i++) {
        if (i == 7) {
            s = (pvtol_real)1 / W[63];
            s = s * s;
        } else {
            s = W[(i * 8) + 7] / W[63];
        }
        P[(i * 8) + 7] = s;
        P[i + 56] = s;
    }
    for (j = 0; j < 8; j++) {
        s = L[0] * P[j];
        D[j] = s;
    }
    for (j = 0; j < 8; j++) {
        s = L[8] * P[j];
        s = s + (L[9] * P[j + 8]);
        D[j + 8] = s;
    }
    for (j = 0; j < 8; j++) {
        s = L[16] * P[j];
        s = s + (L[17] * P[j + 8]);
        s = s + (L[18] * P[j + 16]);
        D[j + 16] = s;
    }
    for (j = 0; j < 8; j++) {
        s = L[24] * P[j];
        s = s + (L[25] * P[j + 8]);
        s = s + (L[26] * P[j + 16]);
        s = s + (L[27] * P[j + 24]);
        D[j + 24] = s;
    }
    for (j = 0; j < 8; j++) {
        s = L[32] * P[j];
        s = s + (L[33] * P[j + 8]);
        s = s + (L[34] * P[j + 16]);
        s = s + (L[35] * P[j + 24]);
        s = s + (L[36] * P[j + 32]);
        D[j + 32] = s;
    }
    for (j = 0; j < 8; j++) {
        s = L[40] * P[j];
        s = s + (L[41] * P[j + 8]);
        s = s + (L[42] * P[j + 16]);
        s = s + (L[43] * P[j + 24]);
        s = s + (L[44] * P[j + 32]);
        s = s + (L[45] * P[j + 40]);
        D[j + 40] = s;
    }
    for (j = 0; j < 8; j++) {
        s = L[48] * P[j];
        s = s + (L[49] * P[j + 8]);
        s = s + (L[50] * P[j + 16]);
        s = s + (L[51] * P[j + 24]);
        s = s + (L[52] * P[j + 32]);
        s = s + (L[53] * P[j + 40]);
        s = s + (L[54] * P[j + 48]);
        D[j + 48] = s;
    }
    for (j = 0; j < 8; j++) {
        s = L[56] * P[j];
        s = s + (L[57] * P[j + 8]);
        s = s + (L[58] * P[j + 16]);
        s = s + (L[59] * P[j + 24]);
        s = s + (L[60] * P[j + 32]);
        s = s + (L[61] * P[j + 40]);
        s = s + (L[62] * P[j + 48]);
        s = s + (L[63] * P[j + 56]);
        D[j + 56] = s;
    }
    for (i = 0; i <= 0; i++) {
        s = D[(i * 8)] * L[0];
        P[(i * 8)] = s;
        P[i] = s;
    }
    for (i = 0; i <= 1; i++) {
        s = D[(i * 8)] * L[8];
        s = s + (D[(i * 8) + 1] * L[9]);
        P[(i * 8) + 1] = s;
        P[i + 8] = s;
    }
    for (i = 0; i <= 2; i++) {
        s = D[(i * 8)] * L[16];
        s = s + (D[(i * 8) + 1] * L[17]);
        s = s + (D[(i * 8) + 2] * L[18]);
        P[(i * 8) + 2] = s;
        P[i + 16] = s;
    }
    for (i = 0; i <= 3; i++) {
        s = D[(i * 8)] * L[24];
        s = s + (D[(i * 8) + 1] * L[25]);
        s = s + (D[(i * 8) + 2] * L[26]);
        s = s + (D[(i * 8) + 3] * L[27]);
        P[(i * 8) + 3] = s;
        P[i + 24] = s;
    }
    for (i = 0; i <= 4; i++) {
        s = D[(i * 8)] * L[32];
        s = s + (D[(i * 8) + 1] * L[33]);
        s = s + (D[(i * 8) + 2] * L[34]);
        s = s + (D[(i * 8) + 3] * L[35]);
        s = s + (D[(i * 8) + 4] * L[36]);
        P[(i * 8) + 4] = s;
        P[i + 32] = s;
    }
    for (i = 0; i <= 5; i++) {
        s = D[(i * 8)] * L[40];
        s = s + (D[(i * 8) + 1] * L[41]);
        s = s + (D[(i * 8) + 2] * L[42]);
        s = s + (D[(i * 8) + 3] * L[43]);
        s = s + (D[(i * 8) + 4] * L[44]);
        s = s + (D[(i * 8) + 5] * L[45]);
        P[(i * 8) + 5] = s;
        P[i + 40] = s;
    }
    for (i = 0; i <= 6; i++) {
        s = D[(i * 8)] * L[48];
        s = s + (D[(i * 8) + 1] * L[49]);
        s = s + (D[(i * 8) + 2] * L[50]);
        s = s + (D[(i * 8) + 3] * L[51]);
        s = s + (D[(i * 8) + 4] * L[52]);
        s = s + (D[(i * 8) + 5] * L[53]);
        s = s + (D[(i * 8) + 6] * L[54]);
        P[(i * 8) + 6] = s;
        P[i + 48] = s;
    }
    for (i = 0; i <= 7; i++) {
        s = D[(i * 8)] * L[56];
        s = s + (D[(i * 8) + 1] * L[57]);
        s = s + (D[(i * 8) + 2] * L[58]);
        s = s + (D[(i * 8) + 3] * L[59]);
        s = s + (D[(i * 8) + 4] * L[60]);
        s = s + (D[(i * 8) + 5] * L[61]);
        s = s + (D[(i * 8) + 6] * L[62]);
        s = s + (D[(i * 8) + 7] * L[63]);
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
