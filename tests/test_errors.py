"""Tests of dice_sweep.errors: a config error is one line naming the file, the key and what is
wrong; the command line prints any user error as that one line and exits with code 2."""

import pytest

from dice_sweep.config import parse_config
from dice_sweep.errors import ConfigError, DiceSweepError
from tests.helpers import CONFIGS, run_cli


def test_a_config_error_is_one_line_of_file_key_and_message():
    error = ConfigError("configs/x.toml", "die.sides", "2 is outside the allowed range [3, 127]")
    assert isinstance(error, DiceSweepError)
    assert str(error) == "configs/x.toml: die.sides: 2 is outside the allowed range [3, 127]"
    assert (error.file, error.key, error.message) == ("configs/x.toml", "die.sides", "2 is outside the allowed range [3, 127]")
    assert ConfigError(CONFIGS / "demo.toml", "k", "m").file == str(CONFIGS / "demo.toml")  # a path, kept as text


def test_the_config_raises_it_with_the_key_at_fault():
    with pytest.raises(ConfigError) as caught:
        parse_config("[die]\nsides = 2\n", "mine.toml")
    assert (caught.value.file, caught.value.key) == ("mine.toml", "die.sides")
    assert "\n" not in str(caught.value)


def test_the_command_line_prints_a_user_error_as_one_line_and_exits_2():
    result = run_cli("roll", CONFIGS / "demo.toml", "--set", "die.sides=2")
    assert result.exit_code == 2 and result.stdout == ""
    assert result.stderr == f"error: {CONFIGS / 'demo.toml'} with --set: die.sides: 2 is outside the allowed range [3, 127], an integer\n"
