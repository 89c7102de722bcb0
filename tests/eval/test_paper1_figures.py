import matplotlib.image

from eval.figures import fig8_part2_b1_r2, fig9_part2_correspondences, write_figures


def test_fig8_and_fig9_are_written_from_an_abis_run(abis_run, tmp_path):
    fig8 = fig8_part2_b1_r2(abis_run, out=tmp_path / "fig8.png")
    fig9 = fig9_part2_correspondences(abis_run, out=tmp_path / "fig9.png")
    for figure in (fig8, fig9):
        image = matplotlib.image.imread(figure)
        assert image.shape[0] > 200 and image.shape[1] > 400 and image.std() > 0.05  # drawn, not blank
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig8.png", "fig9.png"]


def test_write_figures_knows_what_a_run_supports(abis_run, five_frame_run):
    assert [p.name for p in write_figures(abis_run)] == [
        "views.png", "fig8_part2_b1_r2.png", "fig9_part2_correspondences.png"]
    assert [p.name for p in write_figures(five_frame_run)] == ["views.png"]  # render_only: no estimates
