"""DMA tables as instruments write them: rows grouped into measurement sets (isotherms), in any order.

Oracle: the synthetic instrument (petroll.studies.synthetic_dma) records which sweep made each row; the
sets found from the temperatures alone must be those sweeps."""

import pathlib
import warnings

import numpy as np
import pytest

from petroll.model import dma
from petroll.studies.synthetic_dma import POLYMER, RUBBER, main, sweeps, write_table

PLATE = "frequency,storage,loss,temperature"


def test_rows_of_one_sweep_form_one_set_whatever_the_thermocouple_does(tmp_path):
    """21 sweeps and a repeated one at 268.15 K, the recorded temperature wandering by up to ~0.4 K along
    a sweep: the default tolerance (0.5 K) finds the 21 isotherms, the repeat joining its temperature's."""
    rows = write_table(POLYMER, tmp_path / "p.csv")
    data = dma.read_dma(tmp_path / "p.csv", POLYMER.law)
    assert len(data.sets) == 21 and data.tolerance == 0.5
    assert max(s.spread for s in data.sets) > 0.2  # the wander is there, and within the tolerance
    sweep = rows["sweep"]
    for k, s in enumerate(data.sets):
        expected = np.flatnonzero((sweep == k) | ((sweep == 21) & (k == 6)))  # the repeat: 268.15 K
        assert sorted(s.rows) == list(expected)
        assert s.temperature == pytest.approx(np.mean(rows["temperature"][expected]), abs=1e-12)
        assert s.label == str(k + 1) and np.all(np.diff(data.frequency[s.rows]) >= 0)  # by frequency
    assert len(data.sets[6].rows) == 32  # two sweeps at 268.15 K: each frequency twice
    # a set column names the sweeps: the repeat is a set of its own at (nearly) the same temperature
    rows = write_table(POLYMER, tmp_path / "s.csv", sets=True)
    labelled = dma.read_dma(tmp_path / "s.csv", POLYMER.law)
    assert len(labelled.sets) == 22 and labelled.tolerance is None
    for s in labelled.sets:
        assert set(rows["sweep"][s.rows]) == {int(s.label.removeprefix("sweep")) - 1}
    assert "22 sets (the set column)" in dma.describe_sets(labelled)


def test_rows_in_any_order_give_the_same_sets_and_the_same_fit(tmp_path):
    """Rows shuffled (as a master curve merged from sets comes), frequencies repeated exactly: the same
    sets (each by frequency), the same reduced points, the same fit (NNLS is indifferent to row order up
    to round-off)."""
    write_table(RUBBER, tmp_path / "r.csv")
    lines = (tmp_path / "r.csv").read_text().splitlines()
    body = [line for line in lines if line[:1].isdigit()]
    order = np.random.default_rng(4).permutation(len(body))
    (tmp_path / "shuffled.csv").write_text("\n".join([PLATE, *(body[i] for i in order)]) + "\n")
    one = dma.read_dma(tmp_path / "r.csv", RUBBER.law)
    two = dma.read_dma(tmp_path / "shuffled.csv", RUBBER.law)
    assert len(one.sets) == len(two.sets) == 20
    for a, b in zip(one.sets, two.sets):
        assert a.temperature == pytest.approx(b.temperature, abs=1e-9)
        assert np.array_equal(one.frequency[a.rows], two.frequency[b.rows])
        assert np.array_equal(np.sort(one.reduced[a.rows]), np.sort(two.reduced[b.rows]))
    fit_one = dma.fit_prony(one.reduced, one.storage, one.loss)
    fit_two = dma.fit_prony(two.reduced, two.storage, two.loss)
    f = np.geomspace(*fit_one.frequency_range, 300)
    assert np.allclose(fit_one.dynamic(f), fit_two.dynamic(f), rtol=1e-6, atol=0)


@pytest.mark.parametrize("content, allowed", [
    (PLATE + "\n" + "\n".join(f"1,{2e6 + k},1e5,{250 + 0.1 * k:.1f}" for k in range(50)) + "\n",
     "the rows from line 2 at 250 ... 254.9 K chain into one set"),
    ("frequency,storage,loss,set\n1,2e6,1e5,a\n2,2e6,1e5,a\n", "a set column needs a temperature column"),
    (PLATE + ",set\n1,2e6,1e5,300,a\n2,2e6,1e5,300, \n", "line 3: set is empty"),
], ids=["ramp", "set-without-temperature", "empty-label"])
def test_tables_that_are_not_sets_of_isotherms_are_refused_with_one_line(tmp_path, content, allowed):
    (tmp_path / "bad.csv").write_text(content)
    with pytest.raises(dma.DMAError, match="") as info:
        dma.read_dma(tmp_path / "bad.csv", RUBBER.law)
    assert allowed in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(dma.DMAError, match="--tolerance 0: must be a finite number > 0"):
        dma.read_dma(tmp_path / "bad.csv", RUBBER.law, tolerance=0)


@pytest.mark.slow
def test_the_figure_names_the_sets_by_a_colour_bar_not_a_legend_of_every_row(tmp_path):
    from petroll.plot.fit import fit_figure

    write_table(POLYMER, tmp_path / "p.csv")
    data = dma.read_dma(tmp_path / "p.csv", POLYMER.law)
    fit = dma.fit_prony(data.reduced, data.storage, data.loss, per_decade=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # e.g. matplotlib's "constrained_layout not applied"
        figure = fit_figure(data, fit)
        figure.canvas.draw()
    panels, bar = figure.axes[:3], figure.axes[3:]
    assert len(bar) == 1 and "21 sets" in bar[0].get_ylabel()
    legend = [t.get_text() for t in panels[0].get_legend().get_texts()]
    assert legend == [f"fit: {len(fit.moduli)} Maxwell terms"]


def test_the_shipped_instrument_table_is_what_its_generator_writes(tmp_path):
    """runs/polymer-dma.csv is reproducible: written again by the command in its header, byte for byte."""
    shipped = pathlib.Path(__file__).resolve().parents[1] / "runs" / "polymer-dma.csv"
    command = shipped.read_text().splitlines()[1].split("synthetic_dma ")[1].split()
    assert command[0] == "runs/polymer-dma.csv"
    main([str(tmp_path / "polymer-dma.csv"), *command[1:]])
    again = (tmp_path / "polymer-dma.csv").read_text().replace(str(tmp_path / "polymer-dma.csv"),
                                                               "runs/polymer-dma.csv")
    assert again == shipped.read_text()


def test_the_instrument_records_what_its_docstring_says():
    """The synthetic instrument: sweeps from the highest frequency down, temperatures to 4 decimals, the
    moduli within a few noise sigmas of the material's at each row's own temperature."""
    rows = sweeps(RUBBER, seed=1)
    one = rows["sweep"] == 3
    assert np.all(np.diff(rows["frequency"][one]) < 0)
    assert np.array_equal(rows["temperature"], np.round(rows["temperature"], 4))
    E = RUBBER.modulus(rows["frequency"] * 10 ** RUBBER.log10_aT(rows["temperature"]))
    noise = np.concatenate([rows["storage"] / E.real - 1, rows["loss"] / E.imag - 1])
    assert 0.8 * RUBBER.noise < np.std(noise) < 1.2 * RUBBER.noise and np.abs(noise).max() < 5 * RUBBER.noise
