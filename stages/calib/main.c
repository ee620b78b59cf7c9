/* rhoscan-calib: the calib stage as a program (see stages.h and stage.h). */
#include "stage.h"

int main(int argc, char **argv)
{
    return rs_stage_main("calib", argc, argv);
}
