/* SPDX-License-Identifier: MIT */
/*
 * manager/manager_ext.h - the CiA 302-2 manager (core/manager.h), with the
 * CiA 302-3 configuration manager (core/cfgmgr.h) as its configure step,
 * the PDO layout scan (core/pdo_scan.h, into the line's table of layouts,
 * line_pdo_layout) after it and the software manager (core/swmgr.h) as its
 * check software step, on
 * every line that enables it: a line extension (lines/line_ext.h) that
 * feeds the line's core events and time to them, publishes their events
 * on the mailbox (classes BOOT and MANAGER) and answers the MBX_CMD_MGR_*
 * commands. Like gateway/gateway.h: created from plain parameters (no
 * configuration types; apps/cogwd/ext_manager.c fills them), one
 * line_ext per line.
 *
 * Threads: mgr_ext_create/mgr_ext_destroy on the thread that creates and
 * destroys the lines, before they start / after they stopped; everything
 * else on the line thread of its line (each line owns its manager alone,
 * no field is shared between lines or with another thread).
 */
#ifndef COGW_MANAGER_MANAGER_EXT_H
#define COGW_MANAGER_MANAGER_EXT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/manager.h"
#include "core/pdo_layout.h"
#include "lines/line_ext.h"
#include "manager/manager_adopt.h"

#define MGR_EXT_LINES_MAX 16u
#define MGR_EXT_NAME_MAX 32u

/* A node the manager boots: what the line's OD (1F81h, 1F84h..1F88h)
 * does not say. */
typedef struct mgr_ext_node {
	uint8_t id;             /* 1..127 */
	bool keep_op;           /* restart it when it leaves OPERATIONAL */
	uint8_t target_state;   /* NMT state after its boot (core/nmt.h) */
	bool store;             /* 1010h:1 "save" after a configuration download */
	const uint8_t *program; /* the 1F58h:n image (NULL = none); must
	                          * outlive the extension */
	size_t program_len;
	/* its PDO layout (core/pdo_scan.h; docs/config.md "PDO layouts") */
	bool pdo_scan;                       /* learnt by SDO during its boot */
	bool pdo_from_file;                  /* the line's table has it from a file */
	bool pdo_scan_if_reconfigured;       /* ... scanned if 1F22h:n changed */
	const co_pdo_layout_type *pdo_types; /* sorted; must outlive the extension */
	size_t n_pdo_types;
} mgr_ext_node;

typedef struct mgr_ext_line_params {
	bool enabled;                /* false: no manager on this line */
	char name[MGR_EXT_NAME_MAX]; /* for logs */
	co_manager_config mgr;       /* timing and policy; the configure and
	                              * software hooks are set here */
	size_t n_nodes;
	mgr_ext_node nodes[127];
	/* unknown_nodes "boot" (docs/config.md): the device files a node
	 * outside the configuration may match (manager_adopt.h) */
	const mgr_ext_device *devices;
	size_t n_devices;
} mgr_ext_line_params;

typedef struct mgr_ext_params {
	unsigned n_lines; /* 1..MGR_EXT_LINES_MAX */
	mgr_ext_line_params line[MGR_EXT_LINES_MAX];
	size_t msg_size; /* the mailbox's message size: bounds a program
	                  * image that arrives in one message */
} mgr_ext_params;

typedef struct mgr_ext mgr_ext;

/* Returns 0 with *out NULL when no line enables the manager, 0 with *out
 * set, or -EINVAL / -ENOMEM. */
int mgr_ext_create(mgr_ext **out, const mgr_ext_params *p);
void mgr_ext_destroy(mgr_ext *x); /* accepts NULL */
/* The extension of line line_no (out->ops NULL: none on that line). */
void mgr_ext_line(mgr_ext *x, unsigned line_no, line_ext *out);

#endif /* COGW_MANAGER_MANAGER_EXT_H */
