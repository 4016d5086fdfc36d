/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/support/mgr_fixture.h - a CiA 302-2 manager (node 1) and
 * simulated slaves built from the core itself, on the in-memory bus
 * (test_bus.h). The test owns the clock.
 *
 * Typical use: mf_init(); mf_slave() for each device; mf_assign() and
 * mf_expect() to fill the manager's OD; mf_start(); tb_advance().
 * Manager events (CO_EV_MGR_*) are also kept in their own log so that
 * heartbeat traffic cannot push them out.
 */
#ifndef COGW_TESTS_MGR_FIXTURE_H
#define COGW_TESTS_MGR_FIXTURE_H

#include <stdbool.h>
#include <stdint.h>

#include "core/manager.h"
#include "tests/unit/support/test_bus.h"

#define MF_MANAGER_ID 1
#define MF_EVENTS 2048
#define MF_DEVICE_TYPE 0x00040194u
#define MF_VENDOR 0x00000250u
#define MF_PRODUCT 0x00001234u
#define MF_REVISION 0x00010002u

typedef struct mf {
	tb_bus bus;
	tb_port *mp;     /* the manager's port */
	co_manager *mgr; /* NULL until mf_start */
	co_event ev[MF_EVENTS];
	unsigned n_ev;
} mf;

/* Manager node 1 with n_channels SDO client channels and 1F80h = f80. */
void mf_init(mf *f, uint32_t f80, uint8_t n_channels);
void mf_fini(mf *f);

/* A simulated slave: 1000h = MF_DEVICE_TYPE, 1018h = vendor/product/
 * revision/serial(id), heartbeat producer hb_ms (0 = none). Created on the
 * bus now; sends its boot-up at its first tick. */
tb_port *mf_slave(mf *f, uint8_t id, uint16_t hb_ms);
/* Same, with a device type and vendor of the test's choice. */
tb_port *mf_slave_ex(mf *f, uint8_t id, uint16_t hb_ms, uint32_t device_type, uint32_t vendor);

/* 1F81h:id = f81; a heartbeat consumer entry for id with hb_ms (0 none). */
void mf_assign(mf *f, uint8_t id, uint32_t f81, uint16_t hb_ms);
/* 1F84h..1F88h:id */
void mf_expect(mf *f, uint8_t id, uint32_t device_type, uint32_t vendor, uint32_t product,
	       uint32_t revision, uint32_t serial);

/* Create the manager (cfg NULL = defaults) and attach it to the port. */
void mf_start(mf *f, const co_manager_config *cfg);

/* Manager events of a kind; the last BOOT event of a node/step with a
 * status (status -1 = any); count of BOOT events with a status. */
unsigned mf_count(const mf *f, co_event_kind kind);
const co_ev_mgr *mf_boot(const mf *f, uint8_t node, int step, int status);
unsigned mf_boot_count(const mf *f, uint8_t node, int step, int status);
const co_ev_mgr *mf_node_ev(const mf *f, uint8_t node, uint8_t what);
unsigned mf_node_count(const mf *f, uint8_t node, uint8_t what);
/* True if the line went through this state (CO_EV_MGR_STATE). */
bool mf_went_through(const mf *f, uint8_t state);

/* Frames the manager sent with this id and these leading bytes. */
unsigned mf_sent(const mf *f, uint32_t id, const char *hex_prefix);
/* Highest number of SDO requests of the manager in flight at once. */
unsigned mf_max_sdo_in_flight(const mf *f);

#endif
