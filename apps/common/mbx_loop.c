/* SPDX-License-Identifier: MIT */
#include "apps/common/mbx_loop.h"

#include <stdio.h>

/* A registration is a connect(): the daemon answers it at once when it
 * runs, and a daemon that does not run is known without waiting. */
#define ATTACH_MS 1000u

int mbx_loop_open(cogw **h, const cogw_options *o, size_t n_lines, const char *who)
{
	int rc = cogw_loop_open(h, o);

	if (rc < 0)
		return rc;
	for (size_t l = 0; l < n_lines; l++) {
		int ar = cogw_loop_attach(*h, (unsigned)l, ATTACH_MS);

		if (ar < 0)
			fprintf(stderr,
				"%s: line %zu of instance %s: %s (registering at its "
				"first request)\n",
				who, l, o->instance, cogw_strerror(ar));
	}
	return 0;
}

int mbx_loop_send(cogw *h, unsigned line, uint16_t cmd, const void *payload, size_t len,
		  unsigned timeout_ms, uint64_t *corr)
{
	int rc = cogw_loop_send(h, line, cmd, payload, len, timeout_ms, corr);

	if (rc != COGW_E_NOT_REGISTERED)
		return rc;
	rc = cogw_loop_attach(h, line, ATTACH_MS);
	return rc < 0 ? rc : cogw_loop_send(h, line, cmd, payload, len, timeout_ms, corr);
}

int mbx_loop_wait_ms(cogw *h, int want_ms)
{
	int ms = cogw_loop_timeout_ms(h);

	if (ms < 0)
		return want_ms;
	return want_ms >= 0 && want_ms < ms ? want_ms : ms;
}
