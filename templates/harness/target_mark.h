/* Marks for counting on the emulated Cortex-M4F (dfeif-codegen test harness): the benchmark
 * programs' callgrind requests become calls of two functions that do nothing but that the
 * instruction trace finds by address (dfeif_codegen/check/target_count.py). Between two calls of
 * harness_toggle the library's instructions are counted; harness_dump closes a section and prints
 * its name, so the n-th dump in the trace is the n-th "dump" line on stdout. */
#ifndef HARNESS_TARGET_MARK_H
#define HARNESS_TARGET_MARK_H

void harness_toggle(void);
void harness_dump(const char* name);

#define CALLGRIND_TOGGLE_COLLECT harness_toggle()
#define CALLGRIND_DUMP_STATS_AT(name) harness_dump(name)

#endif
