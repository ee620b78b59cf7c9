/* rhoscan-ingest: the ingest stage as a program (see stages.h and stage.h). */
#include "stage.h"

int main(int argc, char **argv)
{
    return rs_stage_main("ingest", argc, argv);
}
