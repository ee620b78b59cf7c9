/* version: see version.h. RHOSCAN_GIT_COMMIT is set for this file alone (CMakeLists.txt), at
 * configure time, so that a new commit recompiles one file, not the project. */
#include "pipeline/version.h"

#ifndef RHOSCAN_GIT_COMMIT
#define RHOSCAN_GIT_COMMIT "unknown"
#endif

const char *rs_version(void)
{
    return "rhoscan " RHOSCAN_VERSION " (git " RHOSCAN_GIT_COMMIT ")";
}

const char *rs_version_commit(void)
{
    return RHOSCAN_GIT_COMMIT;
}
