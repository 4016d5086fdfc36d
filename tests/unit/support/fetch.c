/* SPDX-License-Identifier: MIT */
/* tests/unit/support/fetch.c - see fetch.h. */
#include "tests/unit/support/fetch.h"

#include <stdio.h>
#include <string.h>

const char *fetch_deps_dir(const char *script, char *dir, size_t size)
{
	FILE *p = popen(script, "r");

	if (!p)
		return NULL;
	if (!fgets(dir, (int)size, p))
		dir[0] = '\0';
	if (pclose(p) != 0 || !dir[0])
		return NULL;
	dir[strcspn(dir, "\n")] = '\0';
	return dir;
}
