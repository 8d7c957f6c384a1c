/* YAML walking shared by the loaders: see yaml_doc.h. */
#include "data/yaml_doc.h"

#include <string.h>

sooc_status sooc_ydoc_parse(sooc_ydoc *d, const void *text, size_t n, const char *name) {
    memset(d, 0, sizeof *d);
    d->name = name;
    const unsigned char *in = text;
    unsigned char *copy = NULL;
    size_t off = n >= 3 && in[0] == 0xEF && in[1] == 0xBB && in[2] == 0xBF ? 3 : 0;
    if (n - off >= 6 && !memcmp(in + off, "%YAML:", 6)) {
        /* libyaml refuses OpenCV's "%YAML:1.0" header: blank that line, keep the line numbers */
        copy = sooc_malloc(n);
        if (!copy) return SOOC_ENOMEM;
        memcpy(copy, in, n);
        for (size_t i = off; i < n && copy[i] != '\n'; i++) copy[i] = ' ';
        in = copy;
    }
    yaml_parser_t parser;
    if (!yaml_parser_initialize(&parser)) {
        sooc_free(copy);
        return sooc_seterr(SOOC_ENOMEM, "%s: YAML parser init failed", name);
    }
    yaml_parser_set_input_string(&parser, in, n);
    sooc_status st = SOOC_OK;
    if (!yaml_parser_load(&parser, &d->doc)) {
        st = sooc_seterr(SOOC_EFORMAT, "%s:%d: YAML error: %s%s%s", name, (int)parser.problem_mark.line + 1,
                         parser.problem ? parser.problem : "parse error", parser.context ? " " : "",
                         parser.context ? parser.context : "");
        memset(&d->doc, 0, sizeof d->doc);
    }
    yaml_parser_delete(&parser);   /* the document does not refer to the parser or the text */
    sooc_free(copy);
    return st;
}

void sooc_ydoc_free(sooc_ydoc *d) {
    if (d && d->doc.nodes.start) yaml_document_delete(&d->doc);
    if (d) memset(&d->doc, 0, sizeof d->doc);
}

sooc_status sooc_ymap_pair(sooc_ydoc *d, const yaml_node_t *m, const yaml_node_pair_t *p, const char *ctx,
                           int check_dup, sooc_ypair *out) {
    int top = !ctx || !*ctx;
    out->k = yaml_document_get_node(&d->doc, p->key);
    out->v = yaml_document_get_node(&d->doc, p->value);
    out->key = sooc_yscalar(out->k);
    if (!out->key || !out->v)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s%skeys must be plain strings", d->name,
                           sooc_yline(out->k ? out->k : m), top ? "" : ctx, top ? "" : ": ");
    if (check_dup)
        for (const yaml_node_pair_t *q = m->data.mapping.pairs.start; q < p; q++) {
            const char *k2 = sooc_yscalar(yaml_document_get_node(&d->doc, q->key));
            if (k2 && !strcmp(k2, out->key))
                return sooc_seterr(SOOC_EINVAL, "%s:%d: %s%s%s: duplicate key (first given at line %d)", d->name,
                                   sooc_yline(out->k), top ? "" : ctx, top ? "" : ".", out->key,
                                   sooc_yline(yaml_document_get_node(&d->doc, q->key)));
        }
    return SOOC_OK;
}
