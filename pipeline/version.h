/* version: what `--version` prints and the report cites: the release and the git commit the
 * programs were built from. */
#ifndef RS_VERSION_H
#define RS_VERSION_H

/* "rhoscan 0.1.0 (git 1a2b3c4)", or "(git unknown)" when built outside a git checkout. */
const char *rs_version(void);
/* The commit alone ("1a2b3c4" or "unknown"). */
const char *rs_version_commit(void);

#endif
