/* occluders_ply: reads an occluder PLY (see occluders_ply.h). */
#include "meshing/occluders_ply.h"

#include <math.h>
#include <stdlib.h>
#include "common/faceprop.h"
#include "common/ply.h"

int rs_occluders_read(const char *path, size_t nf, rs_mesh **occ, uint32_t **proxy, rs_err *err)
{
    *occ = NULL;
    *proxy = NULL;
    rs_ply *ply = NULL;
    rs_mesh *m = rs_mesh_read(path, &ply, err);
    if (!m) return -1;
    double *pr = malloc((m->nfaces ? m->nfaces : 1) * sizeof *pr);
    uint32_t *out = malloc((m->nfaces ? m->nfaces : 1) * sizeof *out);
    int rc = -1;
    if (!pr || !out) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory reading the occluders");
    } else if (rs_faceprop_get(ply, path, "proxy", m->nfaces, pr, err) == 0) {
        rc = 0;
        for (size_t f = 0; f < m->nfaces && rc == 0; f++) {
            if (!(pr[f] >= 0 && pr[f] < (double)nf && pr[f] == floor(pr[f])))
                rc = rs_err_set(err, RS_ERR_INPUT, path, 0,
                                "face %zu: proxy %g, expected a facet index of mesh.ply (0 to %zu)", f, pr[f],
                                nf ? nf - 1 : 0);
            else
                out[f] = (uint32_t)pr[f];
        }
    }
    free(pr);
    rs_ply_free(ply);
    if (rc != 0) {
        free(out);
        rs_mesh_free(m);
        return -1;
    }
    *occ = m;
    *proxy = out;
    return 0;
}
