/* SPDX-License-Identifier: MIT */
/*
 * apps/cogwd/extensions.c - the list of extension providers and their
 * start-up and shutdown (see extensions.h).
 */
#include "apps/cogwd/extensions.h"

#include <errno.h>
#include <string.h>

#include "lines/log.h"

extern const cogwd_ext_provider cogwd_ext_manager;
extern const cogwd_ext_provider cogwd_ext_gateway;
extern const cogwd_ext_provider cogwd_ext_devobj;

const cogwd_ext_provider *const cogwd_ext_providers[] = {
	/* the manager and the gateway add their providers here */
	&cogwd_ext_manager,
	&cogwd_ext_gateway,
	&cogwd_ext_devobj,
	NULL,
};

int cogwd_exts_setup(cogwd_exts *x, const cogw_config *cfg)
{
	memset(x, 0, sizeof *x);
	for (unsigned i = 0; cogwd_ext_providers[i]; i++) {
		const cogwd_ext_provider *p = cogwd_ext_providers[i];
		if (i >= LINE_EXT_MAX) {
			cogw_log(COGW_LOG_ERR, "more extension providers than LINE_EXT_MAX (%d)",
				 LINE_EXT_MAX);
			cogwd_exts_teardown(x);
			return -E2BIG;
		}
		int rc = p->setup ? p->setup(cfg, &x->state[i]) : 0;
		if (rc < 0) {
			cogw_log(COGW_LOG_ERR, "extension %s: cannot set up: %s", p->name,
				 strerror(-rc));
			cogwd_exts_teardown(x);
			return rc;
		}
		x->n = i + 1;
	}
	return 0;
}

void cogwd_exts_for_line(const cogwd_exts *x, unsigned line_no, line_ext out[LINE_EXT_MAX])
{
	unsigned k = 0;
	for (unsigned i = 0; i < x->n; i++) {
		const cogwd_ext_provider *p = cogwd_ext_providers[i];
		if (!x->state[i] || !p->line_ext)
			continue; /* not configured */
		line_ext e = { .ops = NULL, .ctx = NULL, .wake_fd = -1 };
		p->line_ext(x->state[i], line_no, &e);
		if (e.ops)
			out[k++] = e;
	}
	for (; k < LINE_EXT_MAX; k++)
		out[k] = (line_ext){ .ops = NULL, .ctx = NULL, .wake_fd = -1 };
}

void cogwd_exts_teardown(cogwd_exts *x)
{
	for (unsigned i = x->n; i-- > 0;) {
		const cogwd_ext_provider *p = cogwd_ext_providers[i];
		if (x->state[i] && p->teardown)
			p->teardown(x->state[i]);
		x->state[i] = NULL;
	}
	x->n = 0;
}
