from dice_sweep.cli import main

main()
