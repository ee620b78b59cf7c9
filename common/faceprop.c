/* faceprop: reading and writing per-facet PLY properties (see faceprop.h). */
#include "common/faceprop.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int rs_faceprop_get(const rs_ply *ply, const char *file, const char *name, size_t nfaces, double *out, rs_err *err)
{
    rs_ply_element *faces = rs_ply_find_element(ply, "face");
    if (!faces) return rs_err_set(err, RS_ERR_INPUT, file, 0, "no 'face' element");
    if (faces->count != nfaces)
        return rs_err_set(err, RS_ERR_INPUT, file, 0, "has %zu faces: expected %zu (same mesh as mesh.ply)",
                          faces->count, nfaces);
    rs_ply_prop *p = rs_ply_find_prop(faces, name);
    if (!p || p->is_list) return rs_err_set(err, RS_ERR_INPUT, file, 0, "face property '%s' is missing", name);
    memcpy(out, p->data, nfaces * sizeof *out);
    return 0;
}

int rs_faceprop_get_rgb(const rs_ply *ply, const char *file, const char *prefix, size_t nfaces, double *out,
                        rs_err *err)
{
    static const char suffix[3] = {'r', 'g', 'b'};
    double *tmp = malloc((nfaces ? nfaces : 1) * sizeof *tmp);
    if (!tmp) return rs_err_set(err, RS_ERR_SYSTEM, file, 0, "out of memory");
    for (int c = 0; c < 3; c++) {
        char name[96];
        snprintf(name, sizeof name, "%s_%c", prefix, suffix[c]);
        if (rs_faceprop_get(ply, file, name, nfaces, tmp, err) != 0) {
            free(tmp);
            return -1;
        }
        for (size_t f = 0; f < nfaces; f++) out[3 * f + c] = tmp[f];
    }
    free(tmp);
    return 0;
}

int rs_faceprop_add_rgb(rs_ply_element *faces, const char *prefix, const double *rgb)
{
    static const char suffix[3] = {'r', 'g', 'b'};
    double *tmp = malloc((faces->count ? faces->count : 1) * sizeof *tmp);
    if (!tmp) return -1;
    for (int c = 0; c < 3; c++) {
        char name[96];
        snprintf(name, sizeof name, "%s_%c", prefix, suffix[c]);
        for (size_t f = 0; f < faces->count; f++) tmp[f] = rgb[3 * f + c];
        if (!rs_ply_add_scalar(faces, name, RS_PLY_FLOAT32, tmp)) {
            free(tmp);
            return -1;
        }
    }
    free(tmp);
    return 0;
}
