"""The CNN + linear SVM: the paper's shapes and loss, training that learns, safe weights, shipped accuracy."""
import numpy as np
import pytest
import torch

from ncbot.vision.classifier import CellClassifier, CellCNN, FitConfig, fit, load_classifier, save_weights, svm_loss, to_input
from ncbot.vision.data import TEST_SEED
from ncbot.vision.data.cells import make_cells
from ncbot.vision.experiments import confusion, paper_experiments, write_report

torch.set_num_threads(1)


def test_paper_architecture_shapes() -> None:
    model = CellCNN()
    convs = [m for m in model.features if isinstance(m, torch.nn.Conv2d)]
    pools = [m for m in model.features if isinstance(m, torch.nn.MaxPool2d)]
    assert [c.out_channels for c in convs] == [8, 16] and [p.kernel_size for p in pools] == [2, 3]
    assert model.svm.in_features == 16 * 6 * 6 and model.svm.out_features == 3
    assert model(torch.zeros(5, 1, 40, 40)).shape == (5, 3)
    assert isinstance(svm_loss(), torch.nn.MultiMarginLoss)


def test_hinge_loss_is_zero_beyond_the_margin() -> None:
    loss = svm_loss()
    assert loss(torch.tensor([[3.0, 1.5, 0.0]]), torch.tensor([0])).item() == 0.0
    assert loss(torch.tensor([[0.0, 1.0, 0.0]]), torch.tensor([0])).item() > 0.5


def test_preprocessing_makes_ink_bright_and_checks_shape() -> None:
    cells, labels = make_cells(6, 1)
    x = to_input(cells)
    assert x.shape == (6, 1, 40, 40) and 0.0 <= x.min() and x.max() <= 1.0
    assert x[labels != 2].mean() > x[labels == 2].mean()
    with pytest.raises(ValueError, match="40, 40"):
        to_input(np.zeros((2, 30, 30), np.uint8))


def test_training_is_seeded_and_learns() -> None:
    images, labels = make_cells(150, 21, noisy_fraction=0.3)
    test, test_labels = make_cells(90, 22)
    config = FitConfig(epochs=6, batch_size=16, seed=3)
    a, b = fit(images, labels, config), fit(images, labels, config)
    for pa, pb in zip(a.parameters(), b.parameters()):
        assert torch.equal(pa, pb)
    accuracy = (CellClassifier(a).predict(test) == test_labels).mean()
    assert accuracy > 0.9


def test_weights_round_trip_and_bad_files(tmp_path) -> None:
    model = CellCNN()
    path = save_weights(model, tmp_path / "w.pt", {"note": "test"})
    cells, _ = make_cells(4, 2)
    assert np.allclose(load_classifier(path).scores(cells), CellClassifier(model).scores(cells))
    assert not list(tmp_path.glob("*.tmp"))
    with pytest.raises(FileNotFoundError, match="do not exist"):
        load_classifier(tmp_path / "missing.pt")
    (tmp_path / "junk.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match="junk.pt could not be loaded .*expected the {state_dict, meta} file"):
        load_classifier(tmp_path / "junk.pt")
    torch.save({"state_dict": {"a": torch.zeros(2)}}, tmp_path / "foreign.pt")
    with pytest.raises(ValueError, match=r"are not a CellCNN's \(missing \['features.0.bias'"):
        load_classifier(tmp_path / "foreign.pt")
    state = model.state_dict()
    state["svm.weight"] = torch.zeros(4, 576)
    torch.save({"state_dict": state}, tmp_path / "other_shape.pt")
    with pytest.raises(ValueError, match="do not fit the CellCNN .*size mismatch for svm.weight"):
        load_classifier(tmp_path / "other_shape.pt")


@pytest.mark.parametrize("styles, floor", [(("pen",), 0.98), (("sketch",), 0.96), (("hershey",), 0.95)])
def test_shipped_weights_on_unseen_cells(styles, floor) -> None:
    """Held-out seeds; 'sketch' and 'hershey' are stroke models never used in training."""
    images, labels = make_cells(300, TEST_SEED + 7, noisy_fraction=0.5, styles=styles)
    accuracy = (load_classifier().predict(images) == labels).mean()
    assert accuracy >= floor, f"{styles}: {accuracy:.3f}"


def test_paper_experiments_small_and_report(tmp_path) -> None:
    results = paper_experiments(FitConfig(epochs=10, batch_size=16, seed=0), loo_folds=2)
    assert [r.n for r in results] == [2, 201, 109]
    assert results[2].accuracy > 0.9  # trained noisy, tested clean (paper: 98.4%)
    for r in results:
        assert r.confusion.sum() == r.n
    paths = write_report(results, tmp_path, "paper")
    assert all(p.stat().st_size > 100 for p in paths)
    assert paths[1].read_bytes()[:4] == b"\x89PNG"
    assert confusion(np.array([0, 1, 2, 2]), np.array([0, 2, 2, 2])).tolist() == [[1, 0, 0], [0, 0, 1], [0, 0, 2]]
