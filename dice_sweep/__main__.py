from dice_sweep.cli import run

run()
