/* SPDX-License-Identifier: MIT */
/*
 * apps/cogwd/extensions.h - the extensions cogwd plugs into its lines (the
 * CiA 302 manager, the CiA 302-7 gateway). lines/ knows none of them: each
 * is a provider that turns the configuration into one line_ext per line
 * (lines/line_ext.h), with whatever it shares between lines (a mesh of
 * cross-line rings, lines/xring.h) created in its setup.
 *
 * To add one: write its provider next to its module and add it to
 * cogwd_ext_providers[] in extensions.c (one line).
 */
#ifndef COGW_APPS_COGWD_EXTENSIONS_H
#define COGW_APPS_COGWD_EXTENSIONS_H

#include "apps/common/config.h"
#include "lines/line_ext.h"

typedef struct cogwd_ext_provider {
	const char *name;
	/* Once, on the main thread, before any line exists. Returns 0 with
	 * *state set (or left NULL: not configured, nothing is plugged in),
	 * or -errno (cogwd does not start). */
	int (*setup)(const cogw_config *cfg, void **state);
	/* For line i of cfg->lines (before line_create): fill *out, or leave
	 * out->ops NULL to stay off that line. */
	void (*line_ext)(void *state, unsigned line_no, line_ext *out);
	/* After every line is destroyed. */
	void (*teardown)(void *state);
} cogwd_ext_provider;

/* NULL-terminated, in the order the extensions see events and commands. */
extern const cogwd_ext_provider *const cogwd_ext_providers[];

/* The running set: state per provider. */
typedef struct cogwd_exts {
	void *state[LINE_EXT_MAX];
	unsigned n;
} cogwd_exts;

/* Set every provider up; on failure, those already set up are torn down. */
int cogwd_exts_setup(cogwd_exts *x, const cogw_config *cfg);
/* Fill the extensions of one line (at most LINE_EXT_MAX). */
void cogwd_exts_for_line(const cogwd_exts *x, unsigned line_no, line_ext out[LINE_EXT_MAX]);
void cogwd_exts_teardown(cogwd_exts *x);

#endif /* COGW_APPS_COGWD_EXTENSIONS_H */
