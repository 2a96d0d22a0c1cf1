/* The runners' drive model: from tick fw_lock_tick (-1: never) ctrl_input.locked reports the
 * joints of fw_lock_mask (bit i: joint i) locked. */
const uint32_t fw_lock_mask = ${lock_mask}u;
const int32_t fw_lock_tick = $lock_tick;
