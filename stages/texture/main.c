/* rhoscan-texture: the texture stage as a program (see stages.h and stage.h). */
#include "stages/stages.h"

int main(int argc, char **argv)
{
    static const rs_stage_def def = RS_STAGE_DEF_TEXTURE;
    return rs_stage_main(&def, argc, argv);
}
