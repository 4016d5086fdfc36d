/* SPDX-License-Identifier: MIT */
/*
 * devobj/mirror.h - the daemon's own PDOs that mirror its slaves' PDOs
 * (docs/devices.md "Automatic mirroring").
 *
 * For a node whose layout is valid (core/pdo_layout.h), every TPDO of the
 * device is consumed by one RPDO of the daemon and every RPDO of the
 * device is produced by one TPDO of the daemon. Each of those daemon PDOs
 * maps one slot object: a UNSIGNED64 sub of the slot arrays
 * DEVOBJ_SLOT_RX_INDEX (values from the devices) and DEVOBJ_SLOT_TX_INDEX
 * (values to the devices), created at start-up, with the frame's whole
 * length; the frame's bytes are the device's mapping as it is, and the
 * device objects in it are found by their bit offsets in the layout.
 *
 * Only records the configuration left alone are used: at start-up a
 * record is free when its COB-ID is invalid (bit 31) and its mapping empty
 * (sub 0 = 0); at programming time it must still be so (an SDO client may
 * have configured it meanwhile). A COB-ID that a valid PDO of the daemon
 * already consumes (device TPDO) or produces (device RPDO) is not
 * mirrored: two PDOs of one node on one COB-ID would fight.
 *
 * Programming follows CiA 301 §7.5.2.35/36 through the OD with the PDO
 * service's own checks (co_od_write): COB-ID invalid, mapping sub 0 = 0,
 * the entry, sub 0 = 1, transmission type, COB-ID valid. Release: COB-ID
 * invalid (back to what it was at start-up), mapping sub 0 = 0.
 *
 * Core only (the OD and the layout table); the extension calls it on the
 * line thread. Allocates only in devobj_mirror_create.
 */
#ifndef COGW_DEVOBJ_MIRROR_H
#define COGW_DEVOBJ_MIRROR_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"
#include "core/pdo.h"
#include "core/pdo_layout.h"

/* The slot arrays (manufacturer-specific area, docs/devices.md). */
#define DEVOBJ_SLOT_RX_INDEX 0x5A00u /* sub n: frame of a device TPDO */
#define DEVOBJ_SLOT_TX_INDEX 0x5A01u /* sub n: frame for a device RPDO */
#define DEVOBJ_SLOTS_MAX 254u        /* subs of one ARRAY */

/* Why a device PDO is not mirrored. */
typedef enum devobj_reason {
	DEVOBJ_R_NONE = 0,
	DEVOBJ_R_NO_RECORD,  /* no free PDO record of the daemon left */
	DEVOBJ_R_COB_IN_USE, /* a hand-written PDO of the daemon uses the COB-ID */
	DEVOBJ_R_OD_REFUSED, /* the daemon's OD refused a re-mapping step */
	DEVOBJ_R_NOT_KEPT,   /* beyond the layout table's room (dropped) */
	DEVOBJ_R_COUNT,
} devobj_reason;

/* "none", "no-free-pdo", "cob-id-in-use", "od-refused", "not-kept". */
const char *devobj_reason_to_string(uint8_t r);

/* State of a node's mirror. */
typedef enum devobj_mirror_status {
	DEVOBJ_M_OFF = 0,     /* not configured for mirroring (pdo not "auto") */
	DEVOBJ_M_WAITING = 1, /* no valid layout yet */
	DEVOBJ_M_FULL = 2,    /* every valid PDO mirrored */
	DEVOBJ_M_PARTIAL = 3, /* some not: see the reason and the PDOs */
	DEVOBJ_M_NONE = 4,    /* none could be mirrored */
} devobj_mirror_status;

const char *devobj_mirror_status_to_string(uint8_t s);

/* One of the daemon's PDO records the mirror may use. */
typedef struct devobj_record {
	uint16_t nr;       /* the daemon's PDO number, 1..512 */
	uint8_t slot_sub;  /* the slot array's sub it maps */
	bool busy;         /* mirrors a device PDO */
	uint8_t node;      /* that device */
	uint16_t dev_pos;  /* its position in the node's layout pdo[] */
	uint32_t idle_cob; /* COB-ID at start-up (bit 31 set), restored on release */
} devobj_record;

/* Per node: which record mirrors which of its PDOs. */
typedef struct devobj_node_mirror {
	bool wanted;         /* pdo "auto" */
	uint8_t status;      /* devobj_mirror_status */
	uint8_t reason;      /* devobj_reason of the first PDO not mirrored */
	uint32_t generation; /* of the layout it mirrors (0: none) */
	bool stale;          /* programmed records were reset: program again */
	uint16_t missing;    /* PDOs not mirrored */
	int16_t *rec[2];     /* [device dir][pos]: record index in the daemon's
	                      * opposite direction, -1 = not mirrored */
	uint8_t *why[2];     /* [device dir][pos]: devobj_reason */
} devobj_node_mirror;

typedef struct devobj_mirror {
	co_node *co;
	co_pdo_layout *layout;
	/* [daemon dir]: CO_PDO_RX records consume device TPDOs, CO_PDO_TX
	 * records produce device RPDOs */
	devobj_record *rec[2];
	uint16_t n_rec[2];
	int16_t *rec_of_nr[2]; /* [daemon dir][nr]: record index, -1 */
	uint16_t n_nr[2];      /* co_pdo_count + 1 */
	devobj_node_mirror node[CO_PDO_LAYOUT_NODES + 1];
	uint32_t refused; /* PDOs left unmirrored, counted per programming */
	uint32_t resets;  /* devobj_mirror_forget calls: our own resets */
} devobj_mirror;

/*
 * Find the free records of the daemon's node, create the slot arrays for
 * them and the per-node tables of the nodes in `wanted` (bit n of word
 * n / 32, as co_pdo_layout_create) and in `room` (NULL = none: nodes that
 * may be wanted later, devobj_mirror_want). Does nothing but zero *m when
 * no node is in either. 0, -EEXIST (a slot array index is defined by the
 * configuration), -ENOMEM.
 */
int devobj_mirror_create(devobj_mirror *m, co_node *co, co_pdo_layout *layout,
			 const uint32_t wanted[4], const uint32_t room[4]);
/* Node `id` is mirrored from now on (at the next devobj_mirror_sync), or
 * no longer (its records are released now). No allocation: -ENOSPC when
 * the node had neither `wanted` nor `room` at creation. */
int devobj_mirror_want(devobj_mirror *m, uint8_t id, bool on);
void devobj_mirror_destroy(devobj_mirror *m);

/* Bring node `id`'s mirror in line with its layout: release what it
 * mirrors, and program it anew when the layout is valid. Returns true when
 * something changed (the caller logs and tells its clients). */
bool devobj_mirror_sync(devobj_mirror *m, uint8_t id);

/* The daemon's own reset communication set every PDO record back to its
 * default: forget what was programmed so that devobj_mirror_sync programs
 * it again. */
void devobj_mirror_forget(devobj_mirror *m);

/* A device RPDO with a deadline (its event timer, CiA 301 §7.5.2.35) must
 * keep receiving: the TPDO record r producing it gets the event timer
 * period_ms, so that the PDO service sends the frame again on its own
 * (CiA 301 §7.2.2.3.2, TT 255 with an event timer). 0 or the abort code. */
uint32_t devobj_mirror_keep_sending(devobj_mirror *m, const devobj_record *r, uint16_t period_ms);

/* The record of the daemon's PDO `nr` in direction `dir` that mirrors,
 * or NULL. */
const devobj_record *devobj_mirror_record_of(const devobj_mirror *m, co_pdo_dir dir, uint16_t nr);

/* The record (daemon direction opposite to `dev_dir`) mirroring the
 * device PDO at `pos` of node `id`, or -1. */
int devobj_mirror_record_for(const devobj_mirror *m, uint8_t id, co_pdo_dir dev_dir, uint16_t pos);

#endif /* COGW_DEVOBJ_MIRROR_H */
