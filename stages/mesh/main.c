/* rhoscan-mesh: the mesh stage as a program (see stages.h and stage.h). */
#include "stage.h"

int main(int argc, char **argv)
{
    return rs_stage_main("mesh", argc, argv);
}
