/* SPDX-License-Identifier: MIT */
/*
 * probe_mbx_loop INSTANCE N - open libcogw, register on line 0 with one
 * OD read of 1018h:01, then N more reads of it, and exit. Run by
 * tests/bench/costs under strace (N and N = 0: the difference is the cost
 * of N round trips, start-up and registration cancel out). Prints the
 * count and the process's context switches, never a pass/fail.
 */
#include <stdio.h>
#include <stdlib.h>
#include <sys/resource.h>

#include "mailbox/cogw.h"

int main(int argc, char **argv)
{
	if (argc != 3) {
		fprintf(stderr, "usage: probe_mbx_loop INSTANCE N\n");
		return 2;
	}
	long n = strtol(argv[2], NULL, 10);
	cogw *h = NULL;
	int rc = cogw_open(&h, argv[1]);
	if (rc < 0) {
		fprintf(stderr, "cogw_open: %s\n", cogw_strerror(rc));
		return 1;
	}
	uint8_t v[4];
	size_t len = 0;
	long failed = 0;
	for (long i = 0; i <= n; i++)
		if (cogw_od_read(h, 0, 0x1018, 1, v, sizeof v, &len, 10000, NULL) < 0)
			failed++;
	cogw_close(h);
	struct rusage ru;
	getrusage(RUSAGE_SELF, &ru);
	printf("probe: %ld round trips after registration, %ld failed, %ld voluntary / %ld "
	       "involuntary context switches\n",
	       n, failed, ru.ru_nvcsw, ru.ru_nivcsw);
	return failed ? 1 : 0;
}
