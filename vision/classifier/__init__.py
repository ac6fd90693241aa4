"""The paper's CNN + linear-SVM cell classifier: model, training, loading and batched inference."""
from ncbot.vision.classifier.inference import DEFAULT_WEIGHTS, CellClassifier, load_classifier, save_weights
from ncbot.vision.classifier.model import CellCNN, svm_loss
from ncbot.vision.classifier.preprocess import to_gray_cell, to_input
from ncbot.vision.classifier.train import FitConfig, fit

__all__ = ["DEFAULT_WEIGHTS", "CellCNN", "CellClassifier", "FitConfig", "fit", "load_classifier",
           "save_weights", "svm_loss", "to_gray_cell", "to_input"]
