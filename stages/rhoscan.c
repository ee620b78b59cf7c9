/* rhoscan: the driver (pipeline/driver.h) over the pipeline's stages (stages/stages.h). */
#include "pipeline/driver.h"
#include "stages/stages.h"

int main(int argc, char **argv)
{
    return rs_driver_main(rs_stage_table, argc, argv);
}
