/* The marks of target_mark.h: kept out of line (the trace finds them by address). */
#include "target_mark.h"

#include <stdio.h>

__attribute__((noinline)) void harness_toggle(void)
{
    __asm volatile("" ::: "memory");
}

__attribute__((noinline)) void harness_dump(const char* name)
{
    printf("dump %s\n", name);
}
