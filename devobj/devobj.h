/* SPDX-License-Identifier: MIT */
/*
 * devobj/devobj.h - process data by the devices' own objects
 * (docs/devices.md): a line extension (lines/line_ext.h) that
 *   - mirrors the PDOs of the slaves configured with pdo "auto" on PDOs of
 *     the daemon (devobj/mirror.h), following the line's learned layouts
 *     (core/pdo_layout.h);
 *   - keeps the last value of every mirrored device object and sends it,
 *     decoded by its CiA 301 type (devobj/value.h), to the clients that
 *     watch it (MBX_CMD_DEV_WATCH, MBX_EV_DEV_VALUE);
 *   - reads a device object from the mirror when it is fresh, else by SDO,
 *     and writes one by the device's RPDO when the mirror produces it,
 *     else by SDO (MBX_CMD_DEV_READ/WRITE), through the line's one mailbox
 *     SDO transfer (line_sdo_submit);
 *   - answers MBX_CMD_DEV_LAYOUT with the learned layouts and the mirror.
 *
 * Like manager/manager_ext.h: plain parameters (apps/cogwd/ext_devobj.c
 * fills them from the configuration), one line_ext per line.
 * Threads: devobj_create/destroy on the thread that creates and destroys
 * the lines; everything else on the line thread of its line.
 */
#ifndef COGW_DEVOBJ_DEVOBJ_H
#define COGW_DEVOBJ_DEVOBJ_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/pdo_layout.h"
#include "lines/line_ext.h"

#define DEVOBJ_LINES_MAX 16u
#define DEVOBJ_NAME_MAX 32u

#define DEVOBJ_FORWARDS_MAX 64u

/* One end of a forwarded device object (gateway.forward, docs/gateway.md):
 * on the source line a TPDO value of the device goes into the process image
 * object `image`; on the target line the image's value goes into the
 * device's RPDO. */
typedef struct devobj_forward {
	bool source;  /* this line holds the `from` end */
	uint8_t node; /* the device object on this line */
	uint8_t sub;
	uint16_t index;
	uint16_t image; /* B-object (sub 0, UNSIGNED64) */
	uint8_t peer_line, peer_node, peer_sub;
	uint16_t peer_index;
} devobj_forward;

/* What a node's file (or the configuration's "types") says of its objects,
 * mapped or not: the type and access of each (sorted, core/pdo_layout.h). */
typedef struct devobj_node_objects {
	const co_pdo_layout_type *list; /* must outlive the extension */
	size_t n;
} devobj_node_objects;

typedef struct devobj_line_params {
	char name[DEVOBJ_NAME_MAX];       /* for logs */
	uint32_t mirror_nodes[4];         /* bit n of word n / 32: node n has pdo "auto" */
	uint32_t room_nodes[4];           /* nodes that may be added at run time
	                                   * (the line has a manager): their
	                                   * mirror tables are made at start-up */
	uint32_t read_max_age_ms;         /* DEV_READ from the mirror when the value is
	                             * at most this old (request's max_age 0) */
	uint32_t write_update_ms;         /* writes to one RPDO of a device within this
	                             * time go out in one frame */
	uint16_t watches;                 /* watch table size of the line */
	devobj_node_objects objects[128]; /* [node id] */
	devobj_forward fwd[DEVOBJ_FORWARDS_MAX];
	uint8_t n_fwd;
} devobj_line_params;

typedef struct devobj_params {
	unsigned n_lines; /* 1..DEVOBJ_LINES_MAX */
	devobj_line_params line[DEVOBJ_LINES_MAX];
} devobj_params;

typedef struct devobj devobj;

/* 0 with *out set, or -EINVAL / -ENOMEM. */
int devobj_create(devobj **out, const devobj_params *p);
void devobj_destroy(devobj *x); /* accepts NULL */
/* The extension of line line_no. */
void devobj_line_ext(devobj *x, unsigned line_no, line_ext *out);

#endif /* COGW_DEVOBJ_DEVOBJ_H */
