"""Body model data (CC0 MakeHuman assets), shipped inside the wheel as vfit_engine.data."""
