/* SPDX-License-Identifier: MIT */
/*
 * apps/cogw-mqtt/mqtt_watch.h - process values (docs/mqtt.md "Process
 * values"): the one place where the bridge meets the daemon's typed watch
 * of device objects (MBX_CMD_DEV_WATCH / DEV_UNWATCH, MBX_EV_DEV_VALUE).
 * A watch names net, node, index, sub, a type and a minimum interval; the
 * daemon sends at most one value per interval (the latest when it ends),
 * and the bridge publishes each on
 *   <prefix>/<gateway>/net/<net>/node/<node>/value/<index>/<sub>  (retained)
 * Watches come from the configuration ("watch", armed once the bridge is
 * subscribed to the line) and from watch_add / watch_remove requests.
 */
#ifndef COGW_MQTT_WATCH_H
#define COGW_MQTT_WATCH_H

#include <stdbool.h>
#include <stddef.h>

#include "apps/cogw-mqtt/bridge.h"

/* The object of a watch_add / watch_remove request. */
mqtt_watch_cfg mqtt_watch_of(const mqtt_request *r);
/* The mailbox command and payload (at least sizeof(mbx_dev_watch_req)
 * bytes) that adds or removes watch w; returns the payload's length. */
size_t mqtt_watch_command(const mqtt_watch_cfg *w, bool add, uint16_t *cmd, void *payload);
/* The daemon's answer (status 0 = done) to such a command on `line`. */
void mqtt_watch_answered(bridge *b, unsigned line, const mqtt_watch_cfg *w, bool add, int status);
/* Arm the configured watches of a line (after its subscription) and renew
 * those in force (every counters period). */
void mqtt_watch_arm(bridge *b, unsigned line);
/* Go on arming the configured watches never answered yet: the bridge has
 * only so many requests of its own under way (INTERNAL_SLOTS), a long list
 * is armed as their answers free them. */
void mqtt_watch_arm_rest(bridge *b, unsigned line);
/* MBX_EV_DEV_VALUE: publish the value of a watched object. */
void mqtt_watch_on_value(bridge *b, const cogw_msg *m);
/* Why a watch command failed, for the reply and the log. */
const char *mqtt_watch_refusal(int status);

#endif /* COGW_MQTT_WATCH_H */
