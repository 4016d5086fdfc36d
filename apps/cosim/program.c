/* SPDX-License-Identifier: MIT */
/*
 * apps/cosim/program.c - the simulated device's program download objects
 * (CiA 302-3 software manager's counterpart): 1F50h:1 program data written
 * into a simulated flash, 1F51h:1 program control with a small state
 * machine (stopped, running, cleared), 1F56h:1 application software
 * identification. Contract in cosim.h (cosim_program_attach).
 *
 * Image check on start: the last 4 bytes are the CRC-32 of the rest, so a
 * test (or the software manager's integration test) can hand a good and a
 * corrupted image and see the device run one and refuse the other.
 *
 * The flash and the program state are the device's, not parameters: NMT
 * resets (which put 1000h-1FFFh back to their defaults) and 1011h must
 * not touch them, so every change here makes the new value the default
 * too (cosim_program_pin). At power-on the device runs a good image in its flash,
 * as a boot loader does (docs/cosim.md "Program download").
 */
#include <errno.h>
#include <string.h>

#include "apps/cosim/cosim.h"

#define AB_INVALID_VALUE 0x06090030u /* invalid value for parameter */
#define AB_CANNOT_STORE 0x08000020u  /* data cannot be transferred or stored */
#define AB_STATE 0x08000022u         /* ... because of the present device state */

enum prog_cmd {
	CMD_STOP = 0,
	CMD_START = 1,
	CMD_RESET = 2,
	CMD_CLEAR = 3
};

static const char *state_name(uint8_t s)
{
	switch (s) {
	case COSIM_PROG_STOPPED:
		return "stopped";
	case COSIM_PROG_RUNNING:
		return "running";
	case COSIM_PROG_CLEARED:
		return "cleared";
	}
	return "?";
}

void cosim_program_pin(cosim_program *p)
{
	co_od_entry *flash = co_od_find(p->od, 0x1F50, 1);
	co_od_entry *control = co_od_find(p->od, 0x1F51, 1);
	co_od_entry *id = co_od_find(p->od, 0x1F56, 1);
	int rc;

	if (!flash || !control || !id)
		return;
	rc = co_od_entry_set_default_bytes(flash, flash->data, flash->size);
	if (rc)
		cosim_log(p->quiet, "node %u: flash kept until the next reset only: %s", p->node_id,
			  strerror(-rc));
	co_od_entry_set_default_bytes(control, control->data, control->size);
	co_od_entry_set_default_bytes(id, id->data, id->size);
}

static void set_state(cosim_program *p, uint8_t s)
{
	if (p->state != s)
		cosim_log(p->quiet, "node %u: program %s -> %s", p->node_id, state_name(p->state),
			  state_name(s));
	p->state = s;
	co_od_set_u8(p->od, 0x1F51, 1, s);
	cosim_program_pin(p);
}

/* The image in the flash, and whether its CRC holds. */
static bool image_ok(const cosim_program *p, uint32_t *crc)
{
	const co_od_entry *e = co_od_find(p->od, 0x1F50, 1);
	uint32_t want;

	if (!e || e->size < 5)
		return false;
	want = (uint32_t)e->data[e->size - 4] | (uint32_t)e->data[e->size - 3] << 8 |
	       (uint32_t)e->data[e->size - 2] << 16 | (uint32_t)e->data[e->size - 1] << 24;
	*crc = cosim_crc32(e->data, e->size - 4);
	return *crc == want;
}

static uint32_t data_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	cosim_program *p = ctx;

	(void)e;
	(void)a;
	/* new firmware only into an erased flash (stop, clear, download) */
	return p->state == COSIM_PROG_CLEARED ? 0 : AB_STATE;
}

static void data_written(void *ctx, co_od_entry *e, const co_od_access *a)
{
	cosim_program *p = ctx;

	(void)a;
	p->image_len = e->size;
	cosim_log(p->quiet, "node %u: program image of %u bytes in flash", p->node_id,
		  (unsigned)e->size);
	set_state(p, COSIM_PROG_STOPPED);
}

/* Decide on a 1F51h:1 write: the stored value is the state, so the hook
 * applies the command itself and the write then stores the new state. */
static uint32_t control_check(void *ctx, co_od_entry *e, const co_od_access *a)
{
	cosim_program *p = ctx;
	uint32_t crc = 0;
	uint8_t cmd;

	(void)e;
	if (!a->data || a->size != 1)
		return 0; /* size errors are the OD's */
	cmd = a->data[0];
	switch (cmd) {
	case CMD_STOP:
		if (p->state == COSIM_PROG_RUNNING)
			set_state(p, COSIM_PROG_STOPPED);
		return 0;
	case CMD_CLEAR:
		if (p->state == COSIM_PROG_RUNNING)
			return AB_STATE;
		co_od_set_bytes(p->od, 0x1F50, 1, "", 0);
		p->image_len = 0;
		co_od_set_u32(p->od, 0x1F56, 1, 0);
		set_state(p, COSIM_PROG_CLEARED);
		return 0;
	case CMD_START:
	case CMD_RESET:
		if (p->state == COSIM_PROG_RUNNING && cmd == CMD_START)
			return 0;
		if (p->state == COSIM_PROG_CLEARED)
			return AB_STATE;
		if (p->desc->refuse || !image_ok(p, &crc)) {
			p->refused++;
			set_state(p, COSIM_PROG_STOPPED);
			cosim_log(p->quiet, "node %u: program image refused (%s)", p->node_id,
				  p->desc->refuse ? "device refuses images" : "CRC mismatch");
			return AB_CANNOT_STORE;
		}
		co_od_set_u32(p->od, 0x1F56, 1, crc);
		set_state(p, COSIM_PROG_RUNNING);
		return 0;
	default:
		return AB_INVALID_VALUE;
	}
}

/* The write stores the command; put the state back as the read value. */
static void control_written(void *ctx, co_od_entry *e, const co_od_access *a)
{
	cosim_program *p = ctx;

	(void)a;
	co_od_entry_set_raw(e, p->state);
}

static const co_od_hooks data_hooks = { .check_write = data_check, .after_write = data_written };
static const co_od_hooks control_hooks = { .check_write = control_check,
					   .after_write = control_written };

int cosim_program_attach(cosim_program *p, co_od *od, const cosim_program_desc *desc,
			 uint8_t node_id, bool quiet)
{
	const co_od_entry *e = co_od_find(od, 0x1F50, 1);
	uint32_t crc = 0;
	int rc;

	memset(p, 0, sizeof(*p));
	p->od = od;
	p->desc = desc;
	p->quiet = quiet;
	p->node_id = node_id;
	if (!e || !co_od_find(od, 0x1F51, 1) || !co_od_find(od, 0x1F56, 1))
		return -ENOENT;
	/* Power-on: the flash holds the device file's factory image, an image
	 * 1010h saved, or nothing. A good image runs; "refuse" is about the
	 * images a software manager starts, not the one the device boots. */
	p->image_len = e->size;
	if (!e->size)
		p->state = COSIM_PROG_CLEARED;
	else if (image_ok(p, &crc))
		p->state = COSIM_PROG_RUNNING;
	else
		p->state = COSIM_PROG_STOPPED;
	co_od_set_u8(od, 0x1F51, 1, p->state);
	co_od_set_u32(od, 0x1F56, 1, crc);
	cosim_log(quiet, "node %u: program %s at power-on (%u bytes in flash, 1F56h:1 = %08X)",
		  node_id, state_name(p->state), (unsigned)p->image_len, (unsigned)crc);
	cosim_program_pin(p);
	if ((rc = co_od_set_hooks(od, 0x1F50, 1, &data_hooks, p)) ||
	    (rc = co_od_set_hooks(od, 0x1F51, 1, &control_hooks, p)))
		return rc;
	return 0;
}
