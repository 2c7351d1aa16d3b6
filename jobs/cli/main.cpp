// The gimforge executable: all logic lives in jobs/ (cli.cpp parses, cmd_*.cpp run).
#include "jobs/cli/commands.h"

int main(int argc, char** argv) { return gimforge::cli::main(argc, argv); }
