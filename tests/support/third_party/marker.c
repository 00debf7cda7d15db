/* block.c with a constructor that runs when the shared library is loaded (before
 * any FMI function is called) and writes the file MARKER_FILE: the FMU an attacker
 * would upload to run code on the server's machine.  dsim serve must never load it
 * to inspect it; a run (the user's choice) does load it, which the test checks too,
 * so that the marker's absence means something.
 * Compiled with -DMARKER_FILE='"/path/of/marker"'. */
#include "block.c"

#ifndef MARKER_FILE
#error "compile with -DMARKER_FILE='\"/path\"'"
#endif

__attribute__((constructor)) static void leave_a_marker(void) {
    FILE *file = fopen(MARKER_FILE, "a");
    if (file) {
        fputs("loaded\n", file);
        fclose(file);
    }
}
