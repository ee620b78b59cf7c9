/* stages: the pipeline's stages in order, with what each reads and writes; the driver and
 * the rerun decisions are built on this table. */
#include "stages/stages.h"

const rs_stage_def rs_stage_table[] = {
    RS_STAGE_DEF_INGEST,  RS_STAGE_DEF_MESH,       RS_STAGE_DEF_CALIB,
    RS_STAGE_DEF_OBSERVE, RS_STAGE_DEF_IRRADIANCE, RS_STAGE_DEF_REFLECTANCE,
    RS_STAGE_DEF_RENDER,  RS_STAGE_DEF_TEXTURE,    {NULL, NULL, NULL, NULL, NULL, NULL, 0}};

const rs_stage_def *rs_stage_find(const char *name)
{
    return rs_stage_lookup(rs_stage_table, name);
}
