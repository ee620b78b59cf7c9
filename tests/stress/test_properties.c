/* test_properties: properties that hold on any geometry, checked on random terrain inside an
 * open box under a uniform white sky: K's row sums are at most pi, transfer is reciprocal
 * (A_i K_ij = A_j K_ji, summed over random halves of the facets, within sampling error), the
 * forward solve conserves energy, and the reflectance stage's albedo does not change when every
 * radiance is scaled by the same factor (camera gain cancels). */
#include "tests/stress/stress.h"

static uint32_t rng = 12345;
static double uniform01(void)
{
    rng = rng * 1664525u + 1013904223u;
    return (rng >> 8) / 16777216.0;
}

/* Random terrain (a height field from random sinusoids on a 6 x 6 grid, normals up) inside four
 * walls (z from 0.6 to 2, normals inward), open at the top and below the walls' foot. Every
 * ray that leaves a facet's front and comes back hits a front face, so the kernel must be
 * reciprocal; the random heights vary the geometry. */
static rs_mesh *random_scene(void)
{
    rs_meshgen g = rs_meshgen_new(49 + 4 * 16, 72 + 4 * 18);
    rs_meshgen_rect(&g, rs_v3_make(0, 0, 0), rs_v3_make(2, 0, 0), rs_v3_make(0, 2, 0), 6, 6); /* +z */
    size_t nterrain_v = g.nv;
    double amp[4], fx[4], fy[4], ph[4];
    for (int k = 0; k < 4; k++) {
        amp[k] = 0.06 * uniform01();
        fx[k] = 4 * uniform01();
        fy[k] = 4 * uniform01();
        ph[k] = 6.28 * uniform01();
    }
    for (size_t v = 0; v < nterrain_v; v++) {
        double x = g.m->verts[3 * v], y = g.m->verts[3 * v + 1], z = 0.3;
        for (int k = 0; k < 4; k++) z += amp[k] * sin(fx[k] * x + fy[k] * y + ph[k]);
        g.m->verts[3 * v + 2] = (float)z;
    }
    rs_meshgen_rect(&g, rs_v3_make(0, 0, 0.6), rs_v3_make(0, 0, 1.4), rs_v3_make(2, 0, 0), 3, 3); /* y=0, +y */
    rs_meshgen_rect(&g, rs_v3_make(0, 2, 0.6), rs_v3_make(2, 0, 0), rs_v3_make(0, 0, 1.4), 3, 3); /* y=2, -y */
    rs_meshgen_rect(&g, rs_v3_make(0, 0, 0.6), rs_v3_make(0, 2, 0), rs_v3_make(0, 0, 1.4), 3, 3); /* x=0, +x */
    rs_meshgen_rect(&g, rs_v3_make(2, 0, 0.6), rs_v3_make(0, 0, 1.4), rs_v3_make(0, 2, 0), 3, 3); /* x=2, -x */
    rs_mesh *m = rs_meshgen_done(&g);
    rs_v3 c, n;
    double a;
    rs_mesh_face(m, 0, &c, &n, &a);
    assert_true(n.z > 0.5); /* terrain faces up */
    rs_mesh_face(m, m->nfaces - 1, &c, &n, &a);
    assert_true(n.x < -0.99); /* the last wall faces inward */
    return m;
}

static void test_kernel_properties(void **state)
{
    rs_mesh *m = random_scene();
    size_t nf = m->nfaces;
    const int N = 2048;
    rs_transport *K = stress_gather_K(m, N, 5);
    double *area = malloc(nf * sizeof *area);
    for (size_t i = 0; i < nf; i++) {
        rs_v3 c, n;
        rs_mesh_face(m, i, &c, &n, &area[i]);
        double rs = stress_row_sum(K, i);
        if (!(rs <= M_PI * (1 + 1e-7))) fail_msg("facet %zu: row sum %.9g > pi", i, rs);
    }
    /* Reciprocity over random halves S, T: sum_{i in S, j in T} A_i K_ij against the reverse.
     * Each side is a sum of hits of weight A_i pi / N; its relative standard error is about
     * 1 / sqrt(hits) (more for unequal areas): allow 5 of them. The two ray-traced transfers
     * agree only if the gather has no directional bias (origin offsets, backfaces). */
    uint8_t *side = malloc(nf);
    double worst = 0;
    for (int trial = 0; trial < 8; trial++) {
        for (size_t i = 0; i < nf; i++) side[i] = uniform01() < 0.5;
        double st = 0, ts = 0, hits = 0;
        for (size_t i = 0; i < nf; i++)
            for (size_t e = K->row_start[i]; e < K->row_start[i + 1]; e++) {
                uint32_t j = K->col[e];
                if (side[i] && !side[j]) st += area[i] * K->k[e];
                if (!side[i] && side[j]) ts += area[i] * K->k[e];
                if (side[i] != side[j]) hits += K->k[e] * N / M_PI;
            }
        double rel = fabs(st - ts) / (0.5 * (st + ts)), sigma = 2 / sqrt(hits);
        worst = fmax(worst, rel / sigma);
        if (rel > 5 * sigma)
            fail_msg("trial %d: transfer S->T %.6g, T->S %.6g (%.2g apart, sigma %.2g)", trial, st, ts, rel, sigma);
    }
    print_message("reciprocity: worst difference %.2f sigma over 8 random halvings\n", worst);

    /* Energy: sky power in = power absorbed + power leaving through the openings, with
     * E_sky = pi - row sum (white sky) and the forward solution at albedo 0.8. What arrives is
     * counted with the receivers' rays, what leaves with the emitters' rays: the two agree only
     * as far as K is reciprocal. */
    double *rho = malloc(3 * nf * sizeof *rho), *esky = malloc(3 * nf * sizeof *esky);
    double *L = malloc(3 * nf * sizeof *L), *G = malloc(3 * nf * sizeof *G);
    for (size_t i = 0; i < nf; i++) {
        for (int ch = 0; ch < 3; ch++) {
            rho[3 * i + ch] = 0.8;
            esky[3 * i + ch] = M_PI - stress_row_sum(K, i);
        }
    }
    double residual;
    int it = rs_transport_solve(K, rho, esky, L, G, 1e-12, 100000, &residual);
    double in = 0, absorbed = 0, escaped = 0;
    for (size_t i = 0; i < nf; i++) {
        in += area[i] * esky[3 * i];
        absorbed += area[i] * (1 - rho[3 * i]) * (esky[3 * i] + G[3 * i]);
        /* facet i's own rays say which share of its light leaves: 1 - row sum / pi */
        escaped += L[3 * i] * area[i] * (M_PI - stress_row_sum(K, i));
    }
    double imbalance = fabs(in - absorbed - escaped) / in;
    print_message("energy: in %.6g, absorbed %.6g, escaped %.6g; imbalance %.2g (%d iterations)\n", in, absorbed,
                  escaped, imbalance, it);
    assert_true(residual < 1e-12);
    assert_true(imbalance < 0.005); /* a few times 1 / sqrt(hits) over the scene (~0.1 %) */

    /* Gain: albedo from (L, E_sky) and from (c L, c E_sky), c = 1e-3 and 1e4, is the same up to
     * float rounding, and so are the flags. */
    const char *dir = rs_test_tmpdir("gain");
    double *alb[3], *est[3];
    const double gains[3] = {1, 1e-3, 1e4};
    double *Ls = malloc(3 * nf * sizeof *Ls), *Es = malloc(3 * nf * sizeof *Es);
    for (int gi = 0; gi < 3; gi++) {
        for (size_t i = 0; i < 3 * nf; i++) {
            Ls[i] = gains[gi] * L[i] * (1 + 0.2 * ((i % 7) / 7.0 - 0.5)); /* an albedo that varies */
            Es[i] = gains[gi] * esky[i];
        }
        stress_write_reflectance_inputs(dir, m, Ls, Es, NULL, K);
        rs_err err;
        if (stress_run_stage("reflectance", dir, "[reflectance]\nmethod = interreflection\n", &err) != 0)
            fail_msg("reflectance: %s", err.msg);
        stress_read_albedo(dir, nf, &alb[gi], &est[gi]);
    }
    double worst_gain = 0;
    size_t nest = 0;
    for (size_t i = 0; i < nf; i++) {
        nest += est[0][i] != 0;
        for (int gi = 1; gi < 3; gi++) {
            assert_true(est[gi][i] == est[0][i]);
            for (int ch = 0; ch < 3; ch++)
                worst_gain =
                    fmax(worst_gain, fabs(alb[gi][3 * i + ch] - alb[0][3 * i + ch]) / fmax(alb[0][3 * i + ch], 1e-30));
        }
    }
    print_message("gain: %zu estimable facets; albedo changes by at most %.2g relative under gains 1e-3 and 1e4\n",
                  nest, worst_gain);
    assert_true(nest > nf / 2);
    assert_true(worst_gain < 1e-5);
    for (int gi = 0; gi < 3; gi++) {
        free(alb[gi]);
        free(est[gi]);
    }
    rs_test_rmtree(dir);
    free(Ls);
    free(Es);
    free(rho);
    free(esky);
    free(L);
    free(G);
    free(side);
    free(area);
    stress_transport_free(K);
    rs_mesh_free(m);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_kernel_properties))
