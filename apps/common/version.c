/* SPDX-License-Identifier: MIT */
#include "apps/common/version.h"

#include <stdio.h>
#include <string.h>

bool cogw_version_asked(const char *program, int argc, char **argv)
{
	/* Before any other check, so that it answers whatever else the line
	 * holds (as GNU programs do); an option's value that reads
	 * "--version" would be taken for the option. */
	for (int i = 1; i < argc; i++) {
		if (strcmp(argv[i], "--") == 0)
			break;
		if (strcmp(argv[i], "--version") == 0) {
			printf("%s %s\n", program, cogw_version);
			return true;
		}
	}
	return false;
}
