from orbitrig.cli import main

main()
